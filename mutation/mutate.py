"""Mutation check of the pure core (issue 18): ``make mutate`` runs this.

A thin driver around mutmut 3 (https://mutmut.readthedocs.io):

* a work directory ``out/mutate/work`` mirrors the repository through symlinks, with a ``tests/`` holding only the
  rooms' test files (plus the shared helpers) and a ``pyproject.toml`` carrying the ``[tool.mutmut]`` section built
  from ``mutation/config.toml``; mutmut keeps its cache there (``mutants/``), so a re-run only re-mutates the
  functions whose source changed (mutmut hashes each function);
* mutants run in parallel (``max_children``) against the room tests that reach the mutated function; when a room's
  test files change, that module's survivors are re-checked; a survivor is then re-run against the module's
  ``fallback`` tests (cached by the mutant's source and those tests' content); a mutant that breaks an import or
  the collection counts as caught (pytest exits 2/3/4);
* ``mutation/equivalents.toml`` lists the mutants that cannot change behaviour, each with its mutated line (checked)
  and a one-line reason;
* the table per module (mutants, caught, survived, equivalent, score) goes to ``out/mutate/table.md`` and
  ``table.json``, each survivor's diff to ``out/mutate/survivors.md``; exit 1 when a module is below the target,
  2 on a bad configuration.

Usage: ``python mutation/mutate.py [--module NAME ...] [--report-only] [--no-fallback]``.
"""

from __future__ import annotations

import argparse
import ast
import difflib
import fnmatch
import glob
import hashlib
import json
import os
import subprocess
import sys
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "mutation" / "config.toml"
EQUIVALENTS = ROOT / "mutation" / "equivalents.toml"
OUT = ROOT / "out" / "mutate"
WORK_ROOT = OUT / "work"  # one work directory per module: out/mutate/work/<module>
STATE = OUT / "state.json"
#: linked into the work directory as they are (mutmut copies them into mutants/)
LINKED = ("board_config", "plant", "firmware_sim", "drivers", "hil_stub", "workbench", "studies", "shm_cli", "bench",
          "docs", "README.md")
SOURCE_PATHS = ("board_config", "firmware_sim", "drivers", "workbench", "studies")
#: pytest exit codes that mean "the tests noticed": failed, interrupted (collection error), internal error, usage
CAUGHT_CODES = {1, 2, 3, 4}
NICENESS = 10
CAUGHT_STATUSES = {"killed", "timeout", "caught by type check", "segfault", "suspicious"}


class ConfigError(Exception):
    pass


@dataclass
class Module:
    name: str
    file: str
    tests: list[str]
    fallback: list[str]
    scope: list[str] = field(default_factory=list)

    @property
    def dotted(self) -> str:
        return self.file.removesuffix(".py").replace("/", ".")

    def globs(self) -> list[str]:
        return [f"{self.dotted}.{s}" for s in self.scope] if self.scope else [f"{self.dotted}.*"]

    def in_scope(self, key: str) -> bool:
        return any(fnmatch.fnmatchcase(key, g) for g in self.globs())

    def existing_tests(self) -> list[str]:
        return [t for t in self.tests if (ROOT / t).is_file()]

    def fallback_tests(self) -> list[str]:
        out: list[str] = []
        for pat in self.fallback:
            for p in sorted(glob.glob(str(ROOT / pat))):
                rel = str(Path(p).relative_to(ROOT))
                if rel not in out:
                    out.append(rel)
        return out


def load_config() -> tuple[dict, list[Module]]:
    try:
        cfg = tomllib.loads(CONFIG.read_text())
        mods = [Module(m["name"], m["file"], list(m["tests"]), list(m.get("fallback", m["tests"])),
                       list(m.get("scope", []))) for m in cfg["module"]]
    except (OSError, tomllib.TOMLDecodeError, KeyError, TypeError) as exc:
        raise ConfigError(f"{CONFIG}: {exc}") from exc
    for m in mods:
        if not (ROOT / m.file).is_file():
            raise ConfigError(f"{CONFIG}: module {m.name}: no file {m.file}")
    return cfg, mods


def _sha(*paths: Path | str) -> str:
    h = hashlib.sha256()
    for p in paths:
        p = Path(p)
        h.update(str(p).encode())
        h.update(p.read_bytes() if p.is_file() else b"<missing>")
    return h.hexdigest()[:16]


def work_dir(m: Module) -> Path:
    return WORK_ROOT / m.name


def prepare_work(m: Module, cfg: dict) -> None:
    """The module's work directory: symlinks to the sources, a tests/ with exactly its room's tests (plus the shared
    helpers), a pyproject whose ``[tool.mutmut]`` mutates only its file. Its mutmut cache lives there."""
    WORK = work_dir(m)
    WORK.mkdir(parents=True, exist_ok=True)
    for name in LINKED:
        link = WORK / name
        if not link.is_symlink():
            link.symlink_to(ROOT / name)
    tests = WORK / "tests"
    tests.mkdir(exist_ok=True)
    wanted = {p.name for p in (ROOT / "tests").iterdir()
              if not p.name.startswith("test_") and p.name != "__pycache__"}
    wanted |= {Path(t).name for t in m.existing_tests()}
    for p in tests.iterdir():
        if p.name not in wanted and p.is_symlink():
            p.unlink()
    for name in sorted(wanted):
        link = tests / name
        if not link.is_symlink():
            link.symlink_to(ROOT / "tests" / name)
    # mutants/tests is a copy: drop test files no longer wanted there
    copied = WORK / "mutants" / "tests"
    if copied.is_dir():
        for p in copied.glob("test_*.py"):
            if p.name not in wanted:
                p.unlink()
    only = [m.file]
    text = (ROOT / "pyproject.toml").read_text()
    section = "\n[tool.mutmut]\n" + "\n".join([
        f"source_paths = {json.dumps(list(SOURCE_PATHS))}",
        f"only_mutate = {json.dumps(only)}",
        'pytest_add_cli_args_test_selection = ["tests"]',
        'pytest_add_cli_args = ["-p", "no:cacheprovider", "-p", "no:randomly", "-q"]',
        f"also_copy = {json.dumps([n for n in LINKED if n not in SOURCE_PATHS])}",
        "use_git_change_detection = false",
        f"max_children = {int(cfg.get('max_children', 2))}",
    ]) + "\n"
    text = text.split("\n[tool.mutmut]\n")[0] + section
    target = WORK / "pyproject.toml"
    if not target.exists() or target.read_text() != text:
        target.write_text(text)


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env.setdefault("NUMBA_CACHE_DIR", str(Path.home() / ".cache" / "mfc-shm" / "numba"))
    env["MPLBACKEND"] = "Agg"
    env["PYTHONHASHSEED"] = "0"
    env["MFC_SHM_THREADS"] = "1"
    env["PYTHONPATH"] = str(ROOT / "mutation")  # for the plugin below only
    env["PYTEST_PLUGINS"] = "hypothesis_profile"  # no shrinking in mutant runs
    return env


def _meta(m: Module) -> dict:
    p = work_dir(m) / "mutants" / (m.file + ".meta")
    return json.loads(p.read_text()) if p.is_file() else {}


def reset_survivors(m: Module, reason: str) -> int:
    """Force a re-check of this module's survivors (its room tests changed)."""
    p = work_dir(m) / "mutants" / (m.file + ".meta")
    if not p.is_file():
        return 0
    data = json.loads(p.read_text())
    n = 0
    for key, code in data.get("exit_code_by_key", {}).items():
        if m.in_scope(key) and code in (0, 5, 33):
            data["exit_code_by_key"][key] = None
            n += 1
    if n:
        p.write_text(json.dumps(data, indent=4))
        print(f"mutate: {m.name}: {n} survivors re-checked ({reason})", file=sys.stderr)
    return n


def skip_equivalents(m: Module) -> None:
    """Mark the listed equivalents as skipped (34) in mutmut's cache: it does not run a mutant with a verdict."""
    p = work_dir(m) / "mutants" / (m.file + ".meta")
    if not p.is_file():
        return
    eqs = {e["mutant"] for e in load_equivalents()}
    data = json.loads(p.read_text())
    codes = data.get("exit_code_by_key", {})
    hit = [k for k in codes if k in eqs and codes[k] in (None, 0)]
    for k in hit:
        codes[k] = 34
    if hit:
        p.write_text(json.dumps(data, indent=4))


def run_mutmut(m: Module, cfg: dict) -> None:
    """``mutmut run`` over the files in ``only_mutate``; no mutant names, so cached verdicts stand (mutmut re-runs
    every mutant it is given by name)."""
    cmd = [sys.executable, str(ROOT / "mutation" / "run_mutmut.py"), "run",
           "--max-children", str(int(cfg.get("max_children", 2)))]
    print("mutate: " + " ".join(cmd), file=sys.stderr)
    r = subprocess.run(cmd, cwd=work_dir(m), env=_env(), stdout=subprocess.DEVNULL)
    if r.returncode != 0:
        print(f"mutate: mutmut exited {r.returncode}", file=sys.stderr)


def _functions(path: Path) -> dict[str, str]:
    """Every function's source in a mutmut-generated file, by name."""
    src = path.read_text()
    lines = src.splitlines()
    return {n.name: "\n".join(lines[n.lineno - 1 : n.end_lineno]) for n in ast.walk(ast.parse(src))
            if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef)}


def mutant_diff(m: Module, key: str, funcs: dict[str, str]) -> list[str]:
    """The changed lines of mutant ``key`` against the original function ('-'/'+' lines)."""
    local = key.removeprefix(m.dotted + ".")
    orig_name = local.rsplit("__mutmut_", 1)[0] + "__mutmut_orig"
    name = local.rsplit(".", 1)[-1]
    a = funcs.get(orig_name, "").splitlines()
    b = funcs.get(name, "").replace(name, orig_name, 1).splitlines()
    return [ln for ln in difflib.unified_diff(a, b, lineterm="", n=0)
            if ln[:1] in "+-" and not ln.startswith(("+++", "---"))]


def fallback_check(m: Module, key: str, diff: list[str], state: dict, tests: list[str]) -> bool:
    """Re-run a survivor against the module's fallback tests; True when they catch it (cached)."""
    fp = hashlib.sha256(("\n".join(diff) + key + "".join(_sha(ROOT / t) for t in tests)).encode()).hexdigest()[:16]
    cache = state.setdefault("fallback", {})
    if cache.get(key, {}).get("fp") == fp:
        return bool(cache[key]["caught"])
    env = _env() | {"MUTANT_UNDER_TEST": key}
    # the repository's test files, importing the mutated packages from mutants/ (the current directory comes first
    # on sys.path with ``python -m``)
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "-m", "not slow",
           "--timeout=600", *(str(ROOT / t) for t in tests)]
    r = subprocess.run(cmd, cwd=work_dir(m) / "mutants", env=env, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)
    caught = r.returncode in (1, 2, 3)  # failed, collection/import broken, internal error (4 = bad usage: not caught)
    cache[key] = {"fp": fp, "caught": caught, "exit": r.returncode}
    return caught


def load_equivalents() -> list[dict]:
    if not EQUIVALENTS.is_file():
        return []
    data = tomllib.loads(EQUIVALENTS.read_text())
    eqs = data.get("equivalent", [])
    for e in eqs:
        if not e.get("mutant") or not e.get("reason"):
            raise ConfigError(f"{EQUIVALENTS}: every entry needs 'mutant' and 'reason': {e}")
    return eqs


def _survivor_codes(code: int | None) -> bool:
    from mutmut.stats import status_by_exit_code

    return code is not None and code not in CAUGHT_CODES and status_by_exit_code[code] not in CAUGHT_STATUSES


def prefetch_fallback(mods: list[Module], state: dict, workers: int) -> None:
    """Run the fallback check of every survivor of the room tests, ``workers`` at a time (each is one pytest run
    of the module's fallback tests: the slowest part of a first run when done one after another)."""
    from concurrent.futures import ThreadPoolExecutor

    eqs = {e["mutant"] for e in load_equivalents()}
    jobs = []
    for m in mods:
        mfile = work_dir(m) / "mutants" / m.file
        fb_tests = m.fallback_tests()
        if not mfile.is_file() or not fb_tests:
            continue
        funcs = _functions(mfile)
        for key, code in _meta(m).get("exit_code_by_key", {}).items():
            if m.in_scope(key) and key not in eqs and _survivor_codes(code):
                jobs.append((m, key, mutant_diff(m, key, funcs), fb_tests))
    if jobs:
        print(f"mutate: fallback tests for {len(jobs)} survivors, {workers} at a time", file=sys.stderr)
        with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
            list(pool.map(lambda j: fallback_check(j[0], j[1], j[2], state, j[3]), jobs))


def tabulate(mods: list[Module], state: dict, fallback: bool) -> tuple[list[dict], list[str], list[str]]:
    from mutmut.stats import status_by_exit_code

    eqs = {e["mutant"]: e for e in load_equivalents()}
    rows: list[dict] = []
    survivors: list[str] = []
    stale: list[str] = []
    for m in mods:
        meta = _meta(m)
        codes = {k: v for k, v in meta.get("exit_code_by_key", {}).items() if m.in_scope(k)}
        mfile = work_dir(m) / "mutants" / m.file
        funcs = _functions(mfile) if mfile.is_file() else {}
        fb_tests = m.fallback_tests()
        row = {"module": m.name, "file": m.file, "mutants": len(codes), "caught": 0, "survived": 0,
               "equivalent": 0, "not_checked": 0, "by_fallback": 0, "survivors": []}
        for key, code in sorted(codes.items()):
            status = status_by_exit_code[code]
            diff = mutant_diff(m, key, funcs)
            if key in eqs:
                line = eqs[key].get("line", "").strip()
                if line and not any(line == d[1:].strip() for d in diff if d.startswith("+")):
                    stale.append(f"{key}: listed line {line!r} not in its diff {diff}")
                else:
                    row["equivalent"] += 1
                    continue
            if status in CAUGHT_STATUSES or code in CAUGHT_CODES:
                row["caught"] += 1
            elif code is None:
                row["not_checked"] += 1
            elif (fallback and fb_tests and fallback_check(m, key, diff, state, fb_tests)) or (
                    not fallback and state.get("fallback", {}).get(key, {}).get("caught")):  # cached verdict
                row["caught"] += 1
                row["by_fallback"] += 1
            else:
                row["survived"] += 1
                row["survivors"].append(key)
                survivors.append(f"### {key} ({status})\n\n```diff\n" + "\n".join(diff) + "\n```\n")
        considered = row["mutants"] - row["equivalent"] - row["not_checked"]
        # no mutant at all means mutmut did not run on the file (a wrong source path, a failing clean run): that is
        # a failure of the check, never a 100 % score
        row["score"] = round(100.0 * row["caught"] / considered, 1) if considered else (
            100.0 if row["mutants"] else 0.0)
        rows.append(row)
    return rows, survivors, stale


def write_table(rows: list[dict], survivors: list[str], stale: list[str], target: float, seconds: float) -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    lines = [f"| module | file | mutants | caught | survived | equivalent | score (%) | ≥ {target:g} % |",
             "| --- | --- | ---: | ---: | ---: | ---: | ---: | --- |"]
    for r in rows:
        ok = "yes" if r["score"] >= target and not r["not_checked"] else "**no**"
        lines.append(f"| {r['module']} | `{r['file']}` | {r['mutants']} | {r['caught']} | {r['survived']} | "
                     f"{r['equivalent']} | {r['score']:.1f} | {ok} |")
    notes = [f"\nscore = caught / (mutants − equivalent); caught includes a survivor of the room tests caught by "
             f"the fallback tests ({sum(r['by_fallback'] for r in rows)} here). Run time {seconds:.0f} s."]
    if any(r["not_checked"] for r in rows):
        notes.append("Not checked yet: " + ", ".join(f"{r['module']} {r['not_checked']}" for r in rows
                                                        if r["not_checked"]))
    if stale:
        notes.append("Stale equivalents (not applied):\n" + "\n".join(f"* {s}" for s in stale))
    (OUT / "table.md").write_text("\n".join(lines + notes) + "\n")
    (OUT / "table.json").write_text(json.dumps({"target_percent": target, "seconds": round(seconds, 1),
                                                "modules": rows, "stale_equivalents": stale}, indent=2) + "\n")
    (OUT / "survivors.md").write_text("# Surviving mutants\n\n" + ("\n".join(survivors) or "none\n"))
    print("\n".join(lines + notes), file=sys.stderr)


def save_state(state: dict) -> None:
    """Write the driver's cache, merging what a concurrent run saved meanwhile (fallback verdicts are additive)."""
    if STATE.is_file():
        disk = json.loads(STATE.read_text())
        for key in ("fallback", "tests", "seconds"):
            state[key] = disk.get(key, {}) | state.get(key, {})
    STATE.parent.mkdir(parents=True, exist_ok=True)
    STATE.write_text(json.dumps(state, indent=1))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--module", action="append", default=[], help="only this module (name in mutation/config.toml)")
    ap.add_argument("--report-only", action="store_true", help="tabulate the cached results, run nothing")
    ap.add_argument("--no-fallback", action="store_true", help="do not re-run survivors against the fallback tests")
    args = ap.parse_args(argv)
    # niceness 10 for the whole run, once: a shared 2-core machine (``make mutate`` already runs under nice 10;
    # re-nicing every child on top of it would starve the run at 19 behind any other work)
    os.nice(max(0, NICENESS - os.nice(0)))
    try:
        cfg, mods = load_config()
        load_equivalents()
    except ConfigError as exc:
        print(f"mutate: {exc}", file=sys.stderr)
        return 2
    names = {m.name for m in mods}
    bad = [n for n in args.module if n not in names]
    if bad:
        print(f"mutate: unknown module {', '.join(bad)} (known: {', '.join(sorted(names))})", file=sys.stderr)
        return 2
    chosen = [m for m in mods if not args.module or m.name in args.module]
    start = time.monotonic()
    state = json.loads(STATE.read_text()) if STATE.is_file() else {}
    if not args.report_only:
        for m in chosen:
            prepare_work(m, cfg)
            fp = _sha(*(ROOT / t for t in m.existing_tests()))
            if state.get("tests", {}).get(m.name) != fp:  # changed, or never recorded
                reset_survivors(m, "its tests changed")
            skip_equivalents(m)
            t0 = time.monotonic()
            run_mutmut(m, cfg)
            state.setdefault("tests", {})[m.name] = fp
            state.setdefault("seconds", {})[m.name] = round(time.monotonic() - t0, 1)
            save_state(state)
    if not args.no_fallback:
        prefetch_fallback(chosen, state, int(cfg.get("max_children", 2)))
        save_state(state)
    rows, survivors, stale = tabulate(chosen, state, fallback=not args.no_fallback)
    save_state(state)
    target = float(cfg.get("target", 95.0))
    write_table(rows, survivors, stale, target, time.monotonic() - start)
    return 0 if all(r["score"] >= target and not r["not_checked"] for r in rows) and not stale else 1


if __name__ == "__main__":
    sys.exit(main())
