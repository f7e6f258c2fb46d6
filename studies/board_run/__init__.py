"""A board run as ``shm run`` reports it: the timeline lines of the board's events (:mod:`.timeline`), the summary,
closing line and traces (:mod:`.summary`), the figures (:mod:`.figures`) and the self-contained HTML report
(:mod:`.report`). The CLI parses the options, drives the run, and calls these."""
