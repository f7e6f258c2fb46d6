"""Build the shipped library's compiled kernels ahead of use: ``python -m plant.warm`` (run by ``make setup``).

A composition's kernels compile on their first use (tens of seconds each, :mod:`plant.compose`) and are cached on
disk by numba (``NUMBA_CACHE_DIR``). This step compiles the compositions the commands use out of the box, so that a
fresh clone's first ``shm model info``, ``shm diagnose``, ``shm run --scenario ...`` or ``shm hil serve`` loads
machine code instead of compiling:

* the nominal model of every shipped parameter set with each terminal: ``amplifier`` and ``open_circuit`` (every
  entry point, the lane integrator included: fits, diagnose, discover, campaigns), ``harvest_coupled`` and
  ``harvest_paper`` (member by member: harvesting, the rig in flight), harvesting without hysteresis too;
* each library effect alone on the nominal model (diagnose's and fit's candidates) with the amplifier terminal
  (every entry point) and the open-circuit one (member by member);
* each shipped scenario's truth plant (its rig effects) with the terminals the rig uses: amplifier, its flight
  terminal and open circuit (member by member).

Combinations found by forward selection and user effect files are compiled when first met (and announced then).
Idempotent: a composition whose entry points are all in the cache is skipped after reading the cache's index (no
machine code loaded), so a second run takes a few seconds. Prints what it builds, with times, on stdout.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, replace

import numpy as np

from plant.compose import KERNEL_ENTRIES
from plant.effect import library_effects
from plant.effects import NOMINAL_EFFECTS
from plant.model import PlantModel
from plant.signals import InputSignals
from plant.stepper import LANE_MIN_BATCH

#: member-by-member entry points (no lane integrator): compositions that integrate one trajectory at a time
MEMBER_ENTRIES = ("run_chunk", "run_chunk_stats", "rhs", "out")
NO_HYSTERESIS = tuple(e for e in NOMINAL_EFFECTS if e != "bouc_wen")


@dataclass(frozen=True)
class ShippedComposition:
    """One composition to build: parameter set, extra effects, terminal, core, and the entry points to compile."""

    params: str
    effects: tuple[str, ...]
    terminal: str
    core: tuple[str, ...] = NOMINAL_EFFECTS
    entries: tuple[str, ...] = MEMBER_ENTRIES
    #: peak memory (bytes) its compile may take; 0 for the ordinary tens-of-MB kernels
    peak_bytes: int = 0

    @property
    def label(self) -> str:
        core = "" if self.core == NOMINAL_EFFECTS else " (no hysteresis)"
        what = " + ".join(os.path.basename(e) for e in self.effects) if self.effects else "nominal"
        lanes = ", lanes" if "run_lanes" in self.entries else ""
        return f"{self.params}: {what}{core}, {self.terminal}{lanes}"

    def model(self) -> PlantModel:
        return PlantModel(self.params, effects=list(self.effects), terminal=self.terminal, core=self.core)


def shipped_compositions() -> list[ShippedComposition]:
    """The compositions the commands use out of the box (see the module docstring), without duplicates."""
    from board_config.parameter_sets import available_parameter_sets
    from board_config.scenario import available_scenarios, load_scenario

    out: list[ShippedComposition] = []
    for params in sorted(available_parameter_sets(), key=lambda n: n != "table2"):  # the default set first
        out += [ShippedComposition(params, (), t, entries=KERNEL_ENTRIES) for t in ("amplifier", "open_circuit")]
        out += [ShippedComposition(params, (), t, core=c) for t in ("harvest_coupled", "harvest_paper")
                for c in (NOMINAL_EFFECTS, NO_HYSTERESIS)]
    for name in library_effects():
        out += [ShippedComposition("table2", (name,), "amplifier", entries=KERNEL_ENTRIES),
                ShippedComposition("table2", (name,), "open_circuit")]
    for scen_name in available_scenarios():
        rig = load_scenario(scen_name).rig
        if rig is None:
            continue
        flight = {"coupled": "harvest_coupled", "paper": "harvest_paper"}.get(rig.coupling, "harvest_coupled")
        out += [ShippedComposition(rig.params, tuple(rig.effects), t) for t in ("amplifier", flight, "open_circuit")]
    unique: dict[tuple[str, ...], ShippedComposition] = {}  # by composition: parameter values are not in a kernel
    for c in out:
        key = c.model().effect_names
        have = unique.get(key)
        entries = tuple(e for e in KERNEL_ENTRIES if e in c.entries or (have is not None and e in have.entries))
        unique[key] = replace(have or c, entries=entries)
    return list(unique.values())


def build(comp: ShippedComposition) -> tuple[str, list[str], float]:
    """Compile ``comp``'s uncached entry points (by calling each as the commands do); (label, built, seconds)."""
    t0 = time.perf_counter()
    model = comp.model()
    todo = model.uncached_kernels(comp.entries)
    if todo:
        model.kernels()  # run_chunk
        inputs = InputSignals(0.0, 1e-3, np.zeros((1, 11, 3)))
        if "run_chunk_stats" in todo:
            model.simulate(inputs, lanes=False, threads=1)
        if "run_lanes" in todo:
            model.simulate(inputs, params=model.param_batch(LANE_MIN_BATCH), lanes=True, threads=1)
        if "rhs" in todo or "out" in todo:
            model.rhs(0.0, model.x0_nominal)
            model.outputs(0.0, model.x0_nominal)
    return comp.label, todo, time.perf_counter() - t0


def main(argv: Sequence[str] | None = None,
         extra: Callable[[], list[ShippedComposition]] | None = None) -> int:
    """The command line; ``extra`` adds the compositions of a layer above the plant (:mod:`workbench.warm`)."""
    ap = argparse.ArgumentParser(prog="python -m plant.warm",
                                 description="Compile the shipped compositions' kernels into numba's cache "
                                             "(NUMBA_CACHE_DIR) so that the first command on a fresh clone is warm.")
    ap.add_argument("--jobs", type=int, default=min(4, os.cpu_count() or 1),
                    help="compositions compiled in parallel processes (default: min(4, CPUs))")
    ap.add_argument("--list", action="store_true", help="list the compositions and whether each is cached; build "
                                                        "nothing")
    args = ap.parse_args(argv)
    if args.jobs < 1:
        ap.error("--jobs must be >= 1")
    t0 = time.perf_counter()
    comps = shipped_compositions() + (extra() if extra is not None else [])
    todo = []
    for c in comps:
        missing = c.model().uncached_kernels(c.entries)
        if args.list:
            print(f"  {'cached ' if not missing else 'to build'}  {c.label}"
                  + (f"  ({', '.join(missing)})" if missing else ""))
        elif missing:
            todo.append(c)
    cache = os.environ.get("NUMBA_CACHE_DIR", "(numba's default: beside each module)")
    if args.list:
        return 0
    if not todo:
        print(f"plant kernels: all {len(comps)} shipped compositions are compiled (cache {cache}); "
              f"checked in {time.perf_counter() - t0:.1f} s")
        return 0
    print(f"plant kernels: compiling {len(todo)} of {len(comps)} shipped compositions into {cache} "
          f"({args.jobs} process(es); tens of seconds each, once per machine) …", flush=True)
    light = [c for c in todo if not c.peak_bytes]
    heavy = [c for c in todo if c.peak_bytes]
    done = _build_all(light, args.jobs, 0, len(todo))
    if heavy:
        peak = max(c.peak_bytes for c in heavy)
        jobs = jobs_for_memory(args.jobs, peak, available_memory_bytes())
        print(f"plant kernels: {len(heavy)} large kernel(s) in {jobs} process(es) (up to {peak / 2**30:.0f} GiB "
              "each) …", flush=True)
        _build_all(heavy, jobs, done, len(todo))
    print(f"plant kernels: done in {time.perf_counter() - t0:.0f} s")
    return 0


def _build_all(comps: list[ShippedComposition], jobs: int, done: int, total: int) -> int:
    """Build ``comps`` in ``jobs`` processes, printing each as it ends (``done`` of ``total`` before); the count
    after."""
    if not comps:
        return done
    with ProcessPoolExecutor(jobs) as pool:
        for future in as_completed([pool.submit(build, c) for c in comps]):
            label, built, seconds = future.result()
            done += 1
            print(f"  [{done}/{total}] {label}: {', '.join(built) or 'already built'} ({seconds:.0f} s)", flush=True)
    return done


def available_memory_bytes() -> int:
    """The memory the machine can give now (bytes): MemAvailable of /proc/meminfo, else the free pages; 0 when
    neither can be read."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_AVPHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return 0


def jobs_for_memory(jobs: int, peak_bytes: int, available_bytes: int) -> int:
    """How many compiles of ``peak_bytes`` each run side by side: no more than ``jobs`` nor than fit in
    ``available_bytes`` (at least one). Two of shm discover's dictionary kernels (12.6 GB each while LLVM optimises
    them, 423 terms) side by side were killed for memory on a 24 GiB machine."""
    return max(1, min(jobs, available_bytes // max(peak_bytes, 1)))


if __name__ == "__main__":
    sys.exit(main())
