"""``--json`` means JSON (issue 11 point 7, issue 15): every command of the parser that has a ``--json`` option
prints exactly one JSON document on stdout — progress, tables, timelines and notes go to stderr — and exits 0.

The commands are discovered from :func:`shm_cli.main.build_parser`, so a command added later is covered without
editing this file: its valid command line comes from :data:`EXAMPLES` when listed there, otherwise it is built
from the parser (record positionals get a synthetic record, required ``--out``/``--save``/``--emit``/``--db``/
``--from`` get paths of the right kind, required choices their first value). A command that cannot be run that way
fails here with a message asking for an entry in :data:`EXAMPLES`."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path

import pytest
from cli_properties_support import assert_ok, shm

from shm_cli.main import build_parser


def _leaf_parsers() -> dict[tuple[str, ...], argparse.ArgumentParser]:
    found: dict[tuple[str, ...], argparse.ArgumentParser] = {}

    def walk(p: argparse.ArgumentParser, path: tuple[str, ...]) -> None:
        subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
        if not subs:
            found[path] = p
            return
        for name, sp in subs[0].choices.items():
            walk(sp, (*path, name))

    walk(build_parser(), ())
    return found


def _has_json(p: argparse.ArgumentParser) -> bool:
    return any("--json" in a.option_strings for a in p._actions)


LEAVES = _leaf_parsers()
JSON_COMMANDS = sorted(path for path, p in LEAVES.items() if _has_json(p))


class Workspace:
    """Inputs the commands need, made once per test process: a short synthetic record, a small finished campaign
    and a usage log of a short run."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.record = root / "step.csv"
        assert_ok(shm("synth", "--test", "step", "--duration-s", 1.5, "--rate-hz", 500, "--out", self.record))
        self.campaign = root / "campaign"
        assert_ok(shm("campaign", "--mbit", "a", "--ranges", "0:20:10", "--n", 3, "--workers", 1, "--no-progress",
                      "--no-figures", "--out", self.campaign))
        self.run = root / "run"
        # `faults` expects no maintenance verdict, so a shortened run still ends as expected (exit 0)
        assert_ok(shm("run", "--scenario", "faults", "--duration-s", 1.0, "--quiet", "--out", self.run))
        self.n = 0

    def visit_records(self) -> list[Path]:
        """Three MBIT.a records stamped with operating hours (the input of `shm health`)."""
        paths = [self.root / f"visit-{h}.csv" for h in (100, 200, 300)]
        for h, path in zip((100, 200, 300), paths):
            if not path.exists():
                assert_ok(shm("synth", "--test", "mbit-a", "--operating-hours", h, "--seed", h, "--out", path))
        return paths

    def fresh(self, name: str) -> Path:
        self.n += 1
        return self.root / f"{name}-{self.n}"


@pytest.fixture(scope="module")
def ws(tmp_path_factory) -> Workspace:
    return Workspace(tmp_path_factory.mktemp("json-ws"))


#: valid, cheap command lines (without --json) for the commands the parser-driven builder cannot guess well
EXAMPLES: dict[tuple[str, ...], Callable[[Workspace], list]] = {
    ("model", "info"): lambda w: [],
    ("campaign",): lambda w: ["--mbit", "a", "--ranges", "0:10:10", "--n", 2, "--workers", 1, "--no-figures",
                              "--out", w.fresh("campaign")],  # progress bar on: it must go to stderr
    ("campaign-roc",): lambda w: ["--from", w.campaign, "--out", w.fresh("roc")],
    ("harvest",): lambda w: ["--duration-s", 0.3, "--out", w.fresh("harvest")],
    # not --quiet: the timeline is printed, and with --json it must go to stderr
    ("run",): lambda w: ["--scenario", "faults", "--duration-s", 2.0, "--timeline-every-s", 0.5,
                         "--out", w.fresh("run")],
    ("synth",): lambda w: ["--test", "step", "--duration-s", 1.0, "--out", w.fresh("synth").with_suffix(".csv")],
    ("compare",): lambda w: [w.record, "--out", w.fresh("compare")],
    ("diagnose",): lambda w: [w.record, "--candidates", "piezo_creep", "--max-rate-hz", 200,
                              "--out", w.fresh("diagnose")],
    ("fit",): lambda w: [w.record, "--add", "piezo_creep", "--max-nfev", 2, "--max-rate-hz", 200,
                         "--save", w.fresh("fit") / "fitted.toml"],
    ("calibrate",): lambda w: ["--free", "k3", "--out", w.fresh("calibrate")],
    ("health",): lambda w: [*w.visit_records(), "--workers", 1, "--out", w.fresh("health")],
    ("effects", "show"): lambda w: ["geometric_stiffening"],
}

#: required options the builder knows how to fill, by destination
_PATHS: dict[str, Callable[[Workspace], object]] = {
    "out": lambda w: w.fresh("out"),
    "save": lambda w: w.fresh("save") / "set.toml",
    "emit": lambda w: w.fresh("emit") / "effect_mod.py",
    "db": lambda w: w.run / "usage.db",
    "source": lambda w: w.campaign,
    "from": lambda w: w.campaign,
}


def build_from_parser(path: tuple[str, ...], w: Workspace) -> list:
    """A command line from the parser alone (see the module doc)."""
    p = LEAVES[path]
    argv: list = []
    for a in p._actions:
        if isinstance(a, argparse._HelpAction) or a.dest == "json":
            continue
        if not a.option_strings:  # positional
            if a.dest in ("records", "record") or (a.metavar or "").upper().startswith("RECORD"):
                argv.append(w.record)
                continue
            raise LookupError(f"positional '{a.dest}'")
        if not a.required:
            continue
        if a.dest in _PATHS:
            argv += [a.option_strings[0], _PATHS[a.dest](w)]
        elif a.choices:
            argv += [a.option_strings[0], next(iter(a.choices))]
        else:
            raise LookupError(f"required option {a.option_strings[0]}")
    return argv


def test_discovery_finds_the_json_commands():
    """The parser walk works: every command known to have --json is found (new ones add to this list)."""
    known = {("model", "info"), ("campaign",), ("campaign-roc",), ("harvest",), ("run",), ("synth",), ("compare",),
             ("diagnose",), ("fit",), ("calibrate",)}
    assert known <= set(JSON_COMMANDS), sorted(known - set(JSON_COMMANDS))


@pytest.mark.parametrize("path", JSON_COMMANDS, ids=lambda p: "-".join(p))
def test_json_is_one_document_on_stdout(path, ws):
    if path in EXAMPLES:
        argv = EXAMPLES[path](ws)
    else:
        try:
            argv = build_from_parser(path, ws)
        except LookupError as exc:
            pytest.fail(f"`shm {' '.join(path)}` has --json but no example: cannot fill {exc} from the parser; "
                        f"add a valid command line to EXAMPLES in {Path(__file__).name}")
    run = shm(*path, *argv, "--json")
    doc = assert_ok(run, json_out=True, allowed=(0,) if path in EXAMPLES else (0, 1))
    assert isinstance(doc, dict) and doc, run.why()
    assert run.out.strip().startswith("{") and run.out.strip().endswith("}"), run.why()


def test_log_export_prints_one_json_document_by_default(ws):
    """`shm log export` has no --json: JSON is its default output, on stdout and nothing else."""
    run = shm("log", "export", "--db", ws.run / "usage.db")
    doc = assert_ok(run, json_out=True)
    assert set(doc) == {"database", "run_id", "tables"}
    assert json.loads(run.out) == doc
