"""Run the benchmarks: ``python -m bench [--out DIR] [--quick] [--only NAME ...] [--scheduler ADDRESS]``
(``--scheduler`` reaches the benchmarks whose ``run`` takes it: the challenges' case loops, docs/scale-out.md)."""

from __future__ import annotations

import argparse
import importlib
import inspect
import json
import sys
import time
from pathlib import Path

#: benchmark modules in order; adding one is one new module plus one line here
BENCHMARKS: tuple[str, ...] = (
    "bench.bench_plant",
    "bench.bench_campaign",
    "bench.bench_harvest",
    "bench.bench_links",
    "bench.bench_stub_latency",
    "bench.bench_board",
    "bench.bench_compare",
    "bench.bench_diagnose",
    "bench.bench_hidden_effect",
    "bench.bench_discover",
    "bench.bench_discovery_challenge",
    "bench.bench_damage_challenge",
    "bench.bench_health",
    "bench.bench_coldstart",
    "bench.bench_live_page",
    "bench.bench_scale_out",
    "bench.bench_single_machine",
)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench", description="mfc-shm benchmarks")
    ap.add_argument("--out", default="out/bench", help="output directory (JSON results and figures)")
    ap.add_argument("--quick", action="store_true", help="smaller sizes (a smoke run, not for quoting)")
    ap.add_argument("--only", nargs="*", default=None, help="run only these benchmark modules (short names)")
    ap.add_argument("--scheduler", default=None, metavar="ADDRESS",
                    help="where the challenges' cases run (hidden_effect, discovery_challenge, damage_challenge, "
                         "health): local (default: two local worker processes), tcp://HOST:PORT (a Dask cluster) "
                         "or synchronous (this process)")
    args = ap.parse_args(argv)
    try:
        from studies.batch.runner import check_scheduler

        check_scheduler(args.scheduler)
    except ValueError as exc:
        ap.error(str(exc))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results = {}
    for name in BENCHMARKS:
        short = name.rsplit(".", 1)[-1]
        if args.only and short not in args.only and short.removeprefix("bench_") not in args.only:
            continue
        print(f"== {short}", flush=True)
        t0 = time.perf_counter()
        module = importlib.import_module(name)
        takes_scheduler = "scheduler" in inspect.signature(module.run).parameters
        res = module.run(out, args.quick, scheduler=args.scheduler) if takes_scheduler else module.run(out, args.quick)
        res["wall_s_total"] = time.perf_counter() - t0
        results[short] = res
        (out / f"{short}.json").write_text(json.dumps(res, indent=2, default=float))
        for key, value in res.items():
            if not isinstance(value, (dict, list)):
                print(f"   {key}: {value}")
    (out / "summary.json").write_text(json.dumps(results, indent=2, default=float))
    print(f"results in {out}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
