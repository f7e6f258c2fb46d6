"""Support of the property-based command-line tests (``tests/shm_cli/test_cli_properties*.py``, issue 15): hypothesis
profiles, running ``shm`` in-process with warnings as errors, checking what a command promised, and strategies
that draw *valid* inputs from the documented ranges.

Profiles: the fast one (default) runs in ``make test`` — few examples, derandomised so the suite is stable; the
long one (``SHM_CLI_FUZZ=1``, ``make fuzz``) draws many more examples at random and keeps its example database in
``.cache/hypothesis`` (ignored by git) so that a failure found once is replayed first on the next run.
``SHM_CLI_FUZZ_EXAMPLES`` overrides the long profile's example count.
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import json
import os
import sqlite3
import tomllib
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st
from hypothesis.database import DirectoryBasedExampleDatabase

REPO = Path(__file__).resolve().parents[1]
FUZZ = os.environ.get("SHM_CLI_FUZZ", "") not in ("", "0")
FUZZ_EXAMPLES = int(os.environ.get("SHM_CLI_FUZZ_EXAMPLES", "50"))
_SUPPRESS = [HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much,
             HealthCheck.function_scoped_fixture]

# fast: no shrinking (a failing example is printed as found; shrinking end-to-end runs can take minutes)
settings.register_profile("shm-cli-fast", max_examples=4, deadline=None, derandomize=True, database=None,
                          phases=(Phase.explicit, Phase.reuse, Phase.generate), suppress_health_check=_SUPPRESS,
                          print_blob=True)
settings.register_profile("shm-cli-fuzz", max_examples=FUZZ_EXAMPLES, deadline=None,
                          database=DirectoryBasedExampleDatabase(str(REPO / ".cache" / "hypothesis")),
                          suppress_health_check=_SUPPRESS, print_blob=True)
PROFILE = settings.get_profile("shm-cli-fuzz" if FUZZ else "shm-cli-fast")


def examples(fast: int, fuzz_factor: float = 1.0) -> settings:
    """Settings of one property: ``fast`` examples in ``make test``, the long profile's count × factor in fuzz."""
    return settings(PROFILE, max_examples=max(1, round(FUZZ_EXAMPLES * fuzz_factor)) if FUZZ else fast)


# --- running shm ----------------------------------------------------------------------------------------------
@dataclass
class CliRun:
    argv: list[str]
    rc: int
    out: str
    err: str

    def why(self) -> str:
        tail = "\n".join(self.err.strip().splitlines()[-12:])
        return f"shm {' '.join(self.argv)}\n-> exit {self.rc}\nstderr (tail):\n{tail}\nstdout (head): {self.out[:400]}"


def shm(*argv: Any) -> CliRun:
    """``shm ARGV`` in this process; stdout and stderr captured; every warning (numpy, matplotlib ...) is an error,
    which the command line reports as a bug (exit 1)."""
    args = [str(a) for a in argv]
    out, err = io.StringIO(), io.StringIO()
    from shm_cli.main import main

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            rc = main(args)
    return CliRun(args, rc, out.getvalue(), err.getvalue())


def assert_ok(run: CliRun, *, allowed: tuple[int, ...] = (0,), json_out: bool = False) -> Any:
    """Exit code allowed, never a bug line or a traceback; with ``json_out`` stdout is exactly one JSON document
    (returned)."""
    assert run.rc in allowed, run.why()
    assert "bug in mfc-shm" not in run.err and "Traceback" not in run.err, run.why()
    if json_out:
        try:
            return json.loads(run.out)  # one document: anything after it is "Extra data"
        except json.JSONDecodeError as exc:
            raise AssertionError(f"--json stdout is not one JSON document ({exc})\n{run.why()}") from None
    return None


def assert_readable(path: Path) -> None:
    """The file exists, is not empty and parses as what its suffix says."""
    path = Path(path)
    assert path.is_file(), f"missing: {path}"
    assert path.stat().st_size > 0, f"empty: {path}"
    suffix = path.suffix.lower()
    if suffix == ".json":
        json.loads(path.read_text())
    elif suffix == ".csv":
        with path.open(newline="") as fh:
            lines = [line for line in fh if not line.startswith("#")]  # a record's TOML header (docs/records.md)
        rows = list(csv.reader(lines))
        assert rows and len(rows[0]) >= 1, path
        widths = {len(r) for r in rows if r}
        assert len(widths) == 1, f"{path}: ragged CSV ({sorted(widths)} columns)"
        if path.read_text()[:200].startswith("# format = \"mfc-shm-"):
            from workbench.records import load_record

            load_record(path)
    elif suffix == ".png":
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", path
        import matplotlib.image

        img = matplotlib.image.imread(path)
        assert img.shape[0] > 50 and img.shape[1] > 50, path
    elif suffix == ".svg":
        assert "<svg" in path.read_text()[:2000], path
    elif suffix == ".npz":
        with np.load(path, allow_pickle=False) as z:
            assert z.files, path
    elif suffix == ".db":
        con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
        try:
            assert con.execute("SELECT count(*) FROM runs").fetchone()[0] >= 1
        finally:
            con.close()
    elif suffix == ".html":
        text = path.read_text()
        assert "<html" in text.lower() and "</html>" in text.lower(), path
    elif suffix == ".toml":
        tomllib.loads(path.read_text())
    elif suffix == ".tdms":
        from workbench.records import load_record

        load_record(path)


# --- strategies: valid inputs from the documented ranges -----------------------------------------------------
def floats(lo: float, hi: float, log: bool = False) -> st.SearchStrategy[float]:
    """Finite floats in [lo, hi], rounded to 4 significant digits (as a user types them); log-uniform on request."""
    if log:
        return st.floats(np.log10(lo), np.log10(hi)).map(lambda e: float(f"{10 ** e:.4g}")).filter(
            lambda v: lo <= v <= hi)
    return st.floats(lo, hi).map(lambda v: float(f"{v:.4g}")).filter(lambda v: lo <= v <= hi)


seeds = st.integers(0, 2**31 - 1)

#: core parameters a user may plausibly re-estimate, and relative factors within ±30 %
_PERTURBABLE = ("k1", "k2", "k3", "c1", "c2", "c3", "m1", "m2", "m3")


@st.composite
def parameter_sets(draw, where: Path) -> str:
    """A shipped parameter set name, or a TOML file of table2 with a few core parameters changed by ±30 %."""
    kind = draw(st.sampled_from(["table2", "calibrated", "file"]))
    if kind != "file":
        return kind
    from board_config import load_parameter_set

    base = load_parameter_set(draw(st.sampled_from(["table2", "calibrated"])))
    names = draw(st.lists(st.sampled_from(_PERTURBABLE), min_size=1, max_size=3, unique=True))
    changes = {n: base.values[n] * draw(floats(0.7, 1.3)) for n in names}
    digest = hashlib.sha1(repr(sorted(changes.items())).encode()).hexdigest()[:10]
    path = where / f"params_{digest}.toml"
    path.write_text(base.with_values(name=path.stem, **changes).to_toml())
    return str(path)


def library_effects() -> dict[str, list[tuple[str, float, float]]]:
    """Library effect → its parameters (name, lower, upper) from the effect classes (documented bounds)."""
    from plant.effect import resolve_effect
    from workbench.fit import LIBRARY

    return {n: [(p.name, p.lower, p.upper) for p in resolve_effect(n).own_parameters()] for n in LIBRARY}


@st.composite
def effect_with_values(draw, strength: float = 0.3) -> tuple[str, dict[str, float]]:
    """A library effect and values for its parameters: within its bounds, towards the mild end (``strength`` of
    the way from the default to a bound), as a user exploring a plausible rig would set them."""
    from plant.effect import resolve_effect

    lib = library_effects()
    name = draw(st.sampled_from(sorted(lib)))
    values: dict[str, float] = {}
    for p in resolve_effect(name).own_parameters():
        lo, hi, d = float(p.lower), float(p.upper), float(p.default)
        a, b = d + strength * (lo - d), d + strength * (hi - d)
        if draw(st.booleans()) and b > a:
            values[p.name] = draw(floats(min(a, b), max(a, b)))
    return name, values
