"""The board firmware mock: 100 Hz scheduler, regimes, condition monitor, MBITs, power manager, usage log.
Pure, deterministic logic; talks to the world only through a ``drivers.Link``."""
