"""The ``shm`` command line: one entry point fronting the whole product."""
