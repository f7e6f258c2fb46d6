"""Benchmarks (``make bench``). Each module exposes ``run(out_dir: Path, quick: bool) -> dict`` and is listed in
:data:`bench.__main__.BENCHMARKS`; results are written as JSON and figures under the output directory, and every
speed figure is quoted as a ratio against a baseline measured in the same run."""
