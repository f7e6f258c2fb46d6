"""Health over time (issue 17): the board's visit records, lives of many visits, per-visit re-estimation, trends,
the forecast of the board's own first FAULT, prognostic metrics and the prognosis challenge.

Modules: :mod:`.laws` (degradation laws), :mod:`.visit_records` (each MBIT's full-rate record, linked in the log),
:mod:`.life` (a life of visits, in parallel), :mod:`.sources` (visits from a run directory, a usage.db or record
files), :mod:`.estimate` (per-visit re-estimation), :mod:`.trend` (model choice, prediction bands), :mod:`.trip`
(the monitor's trip boundary from the campaign machinery), :mod:`.forecast` (P(FAULT) at future hours, trip time,
RUL), :mod:`.metrics` (ProgPy-style metrics), :mod:`.challenge`, :mod:`.report`.
"""
