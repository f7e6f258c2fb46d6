"""Shared report helpers: matplotlib (Agg) figure set-up and decimation, and self-contained HTML pages with the
figures embedded. Every report — ``shm run``, ``compare``, ``diagnose``, ``fit``, ``campaign``, ``harvest`` — draws
with these; what a report shows lives with its owner (the workbench's comparison and diagnosis reports, the
studies' figures).

This layer sits below the workbench and the studies and imports only numpy, matplotlib and ``board_config``.

Modules: :mod:`.figures` (pyplot on Agg, saving — the one place a figure is written, with a hook the tests use —
SI display units, min/max decimation of long traces), :mod:`.figure_layout` (legends above the data, colliding
labels left out, integer and thinned ticks), :mod:`.figure_legibility` (a figure checked as a picture: overlapping
text, legend over data, bars over bars, nan/inf, fractional count ticks), :mod:`.html_page` (embedded images,
tables, the page).
"""
