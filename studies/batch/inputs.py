"""From a folder or a glob of records to tasks (pure apart from listing and reading the named files).

A folder: every record file directly inside it is one task (key: its name without the suffix) and every subfolder
holding record files is a *named group* — one task over all its records together (key: the subfolder's name). A
glob (``'runs/*.csv'``, quoted so the shell leaves it): every match is one task (a matched folder a group). Keys are
unique; two files with the same stem in different places get their parent folder's name in front.
"""

from __future__ import annotations

import glob
from dataclasses import dataclass
from pathlib import Path

from board_config.errors import InputError

#: suffixes of record files (docs/records.md)
RECORD_SUFFIXES = (".csv", ".tdms")
_GLOB_CHARS = set("*?[")


@dataclass(frozen=True)
class BatchTask:
    """One task: its key (sort order and output subfolder) and the files it reads, in order."""

    key: str
    files: tuple[Path, ...]

    def read(self) -> dict[str, bytes]:
        """The task's files by name (what is scattered to the workers once)."""
        return {f.name: f.read_bytes() for f in self.files}


def is_batch_input(items: list[str]) -> bool:
    """True when any input is a folder or a glob pattern: the command then runs once per record or group."""
    return any(_GLOB_CHARS & set(s) or Path(s).is_dir() for s in items)


def _records_in(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in RECORD_SUFFIXES)


def _unit(path: Path, what: str) -> tuple[str, tuple[Path, ...]] | None:
    if path.is_dir():
        files = _records_in(path)
        return (path.name, tuple(files)) if files else None
    if path.is_file():
        return path.stem, (path,)
    raise InputError(f"{what}: {path} is neither a record file nor a folder")


def _units_of(item: str) -> list[tuple[Path, tuple[str, tuple[Path, ...]]]]:
    if _GLOB_CHARS & set(item):
        matches = sorted(Path(m) for m in glob.glob(item))
        if not matches:
            raise InputError(f"the pattern {item!r} matches no file")
        found = [(m, _unit(m, f"pattern {item!r}")) for m in matches]
        return [(m, u) for m, u in found if u is not None]
    path = Path(item)
    if not path.exists():
        raise InputError(f"record {item!r}: no such file or folder")
    if path.is_file():
        return [(path, (path.stem, (path,)))]
    found = [(p, _unit(p, f"folder {item}")) for p in sorted(path.iterdir())
             if p.is_dir() or p.suffix.lower() in RECORD_SUFFIXES]
    units = [(p, u) for p, u in found if u is not None]
    if not units:
        raise InputError(f"folder {item}: no record files (.csv, .tdms) in it or in its subfolders")
    return units


def expand_inputs(items: list[str]) -> list[BatchTask]:
    """The tasks for ``items`` (files, folders, glob patterns), sorted by key; clear errors for what is missing."""
    units = [u for item in items for u in _units_of(item)]
    keys: dict[str, list[tuple[Path, tuple[Path, ...]]]] = {}
    for path, (key, files) in units:
        keys.setdefault(key, []).append((path, files))
    tasks = []
    for key, entries in keys.items():
        if len(entries) == 1:
            tasks.append(BatchTask(key, entries[0][1]))
            continue
        for path, files in entries:  # the same name in two places: the parent folder's name in front
            tasks.append(BatchTask(f"{path.resolve().parent.name}__{key}", files))
    if len({t.key for t in tasks}) != len(tasks):
        raise InputError("two inputs map to the same task name; rename one of the records or folders")
    return sorted(tasks, key=lambda t: t.key)
