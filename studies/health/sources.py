"""Visits from what the user has: a run directory of ``shm run``, its ``usage.db``, or record files.

Records are grouped into visits by their ``operating_hours`` header key (a run's records all carry it when the run
was a ``[life]`` scenario; ``shm synth --operating-hours H`` stamps synthetic ones). The usage log, when at hand,
gives the board's verdict of each visit and MBIT (tables ``mbit_records`` and ``life_visits``).
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Sequence
from pathlib import Path

from board_config.errors import InputError
from studies.health.estimate import Visit, VisitTruth
from workbench.records import Record, load_record


def _records_of_run(run_dir: Path) -> list[Path]:
    rec_dir = run_dir / "records"
    files = sorted(rec_dir.glob("*.csv")) + sorted(rec_dir.glob("*.tdms"))
    if not files:
        raise InputError(f"{run_dir}: no visit records (expected {rec_dir}/visit-NNN_mbit-X.csv, written by shm run "
                         "for every completed MBIT)")
    return files


def _verdicts(db_path: Path) -> tuple[dict[float, str], dict[tuple[float, str], str], dict[float, dict]]:
    """(visit verdicts, MBIT verdicts, the life's truth deviations) by operating hours, from a usage log."""
    visit_v: dict[float, str] = {}
    mbit_v: dict[tuple[float, str], str] = {}
    truth: dict[float, dict] = {}
    if not db_path.exists():
        return visit_v, mbit_v, truth
    try:
        db = sqlite3.connect(f"file:{db_path}?mode=ro", uri=True)
        names = {r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        if "life_visits" in names:
            for h, v, tj in db.execute("SELECT operating_hours, verdict, truth_json FROM life_visits"):
                visit_v[float(h)] = v
                if tj:
                    truth[float(h)] = json.loads(tj)
        if "mbit_records" in names:
            for h, m, v in db.execute("SELECT operating_hours, mbit, verdict FROM mbit_records"):
                if h is not None:
                    mbit_v[(float(h), m)] = v
        db.close()
    except (sqlite3.DatabaseError, json.JSONDecodeError) as exc:
        raise InputError(f"{db_path}: not a usage log ({exc})") from None
    return visit_v, mbit_v, truth


#: the latest plausible operating time of a record (h): about 114 years of continuous operation
MAX_OPERATING_HOURS = 1.0e6


def check_sources(sources: Sequence[str | Path]) -> None:
    """The same source given twice (a path repeated, a record file inside a run directory also given, a run
    directory and its own usage.db): one line naming both (the same visit would count twice)."""
    seen: dict[Path, str] = {}
    for s in sources:
        p = Path(s)
        if not p.exists():
            continue  # load_visits says so, with what a SOURCE may be
        key = p.resolve()
        if p.suffix == ".db":
            key = key.parent
        for owner in (key, *key.parents):
            if owner in seen and (owner == key or (p.is_file() and owner / "records" == key.parent)):
                raise InputError(f"{s}: the same visit data given twice ({seen[owner]} already holds it); give each "
                                 "run directory, usage.db or record file once")
        seen[key] = str(s)


def _check_belonging(f: Path, rec: Record, h: float, groups: dict[float, list[Record]],
                     first: dict[str, tuple[str, str]]) -> None:
    """A record must belong with the others: plausible hours, one record per MBIT and visit, the visit number
    matching its hours, and every board record of one run (``run_uid``) of one board (``board_id``)."""
    if not h <= MAX_OPERATING_HOURS:
        raise InputError(f"{f}: operating_hours = {h:g} h is not a plausible time in a structure's life (at most "
                         f"{MAX_OPERATING_HOURS:g} h)")
    prov = rec.meta.get("provenance", {}) or {}
    if prov.get("generator") == "board":
        for key, what in (("run_uid", "run"), ("board_id", "board")):
            mine = str(prov.get(key, "none (an older record)"))
            if key not in first:
                first[key] = (mine, str(f))
            elif first[key][0] != mine:
                raise InputError(f"{f}: a record of another {what} ({key} {mine}; {first[key][1]} has "
                                 f"{first[key][0]}): a life's visits must come from one run of one board")
    test = str(rec.meta.get("test", ""))
    for other in groups.get(h, []):
        if str(other.meta.get("test", "")) == test:
            raise InputError(f"{f}: a second {test} record of the visit at {h:g} h ({other.path} is one already): "
                             "the same visit given twice")
    vis = prov.get("visit")
    for oh, recs in groups.items():
        ov = (recs[0].meta.get("provenance", {}) or {}).get("visit")
        if prov.get("generator") == "board" and vis is not None and ov == vis and oh != h \
                and (recs[0].meta.get("provenance", {}) or {}).get("generator") == "board":
            raise InputError(f"{f}: visit {vis} at {h:g} h, but {recs[0].path} has visit {vis} at {oh:g} h: "
                             "records of two different lives or runs")


def load_visits(sources: Sequence[str | Path]) -> list[Visit]:
    """Visits (sorted by operating hours) from run directories, usage.db files or record files."""
    files: list[Path] = []
    dbs: list[Path] = []
    for s in sources:
        p = Path(s)
        if not p.exists():
            raise InputError(f"{p}: no such file or directory (a SOURCE is a run directory, its usage.db, or "
                             "record files)")
        if p.is_dir():
            files += _records_of_run(p)
            dbs.append(p / "usage.db")
        elif p.suffix == ".db":
            files += _records_of_run(p.parent)
            dbs.append(p)
        else:
            files.append(p)
    check_sources(sources)
    groups: dict[float, list[Record]] = {}
    first: dict[str, tuple[str, str]] = {}
    for f in files:
        rec = load_record(f)
        if not isinstance(rec, Record):
            raise InputError(f"{f}: a frequency-response table cannot be used for per-visit re-estimation")
        h = rec.meta.get("operating_hours")
        if h is None:
            raise InputError(f"{f}: the record has no 'operating_hours' header key (when in the structure's life it "
                             "was taken; shm synth --operating-hours H stamps it)")
        _check_belonging(f, rec, float(h), groups, first)
        groups.setdefault(float(h), []).append(rec)
    visit_v: dict[float, str] = {}
    mbit_v: dict[tuple[float, str], str] = {}
    life_truth: dict[float, dict] = {}
    for db in dbs:
        a, b, c = _verdicts(db)
        visit_v.update(a)
        mbit_v.update(b)
        life_truth.update(c)
    visits = []
    for i, h in enumerate(sorted(groups)):
        recs = groups[h]
        mv = {}
        for r in recs:
            m = str(r.meta.get("provenance", {}).get("mbit", ""))
            if (h, m) in mbit_v:
                mv[f"MBIT.{m}"] = mbit_v[(h, m)]
        verdict = visit_v.get(h)
        if verdict is None and mv:
            verdict = "FAULT" if "FAULT" in mv.values() else "PASS"
        vis = recs[0].meta.get("provenance", {}).get("visit")
        visits.append(Visit(h, recs, int(vis) if vis is not None else i + 1, verdict, mv,
                            _truth_of(recs, life_truth.get(h))))
    return visits


def _truth_of(recs: Sequence[Record], life_devs: dict | None) -> VisitTruth | None:
    """The visit's truth: the life's deviations from its log, else a synthetic record's ``truth_values``."""
    if life_devs is not None:
        return VisitTruth(str(recs[0].meta.get("params", "table2")), relative=dict(life_devs))
    for r in recs:
        prov = r.meta.get("provenance", {})
        if "truth_values" in prov or prov.get("generator") == "shm synth":
            return VisitTruth(str(prov.get("truth_params", r.meta.get("params", "table2"))),
                              values=dict(prov.get("truth_values") or {}))
    return None
