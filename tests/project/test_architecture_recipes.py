"""The recipes of docs/architecture.md work verbatim, the way a newcomer uses them (issue 30 point 2).

A fresh copy of the repository (its tracked files, as a clone has them) gets every recipe's code block at the place
the block's first line names — ``# path`` a new file, ``# path, in NAME`` inside the table (or class) ``NAME`` after
its last entry, ``# path, before NAME`` just above ``NAME``'s definition — all recipes at once, as one newcomer
adding all of them would. Then, each in a fresh process started in the copy: ``ruff`` and ``mypy`` on the files the
recipes wrote or changed, and every ``$`` command of the page (the affected tests and the recipe's own command),
each expected to succeed, or, where the page shows ``shm: error: ...`` under it, to exit 2 with that line. Before
issue 30 the library effect recipe broke ``import plant`` when copied into ``plant/effects`` and failed the library
tests, the study package had no ``__init__.py`` and the command failed ruff and ignored ``--out``, while the old
form of this test, which wrote the recipes into a separate package after ``plant`` was imported, passed.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "architecture.md"
BIN = Path(sys.executable).parent
#: the first line of a recipe block: where it goes
_PLACE = re.compile(r"^# (?P<path>[\w./-]+\.py)(?:, (?P<how>in|before) (?P<name>\w+))?$")
#: how the page runs the tools: ``shm`` is the installed command (here: the copy's ``shm_cli.main``)
_SHM = [sys.executable, "-c", "import sys; from shm_cli.main import main; sys.exit(main())"]
_TIMEOUT_S = 900

pytestmark = pytest.mark.slow  # ~2-4 min: one copy, ruff, mypy, the library tests of the new effect, eight commands


@dataclass(frozen=True)
class Block:
    path: str
    how: str  # "new", "in" or "before"
    name: str
    code: str


@dataclass(frozen=True)
class Command:
    line: str
    error: str  # the "shm: error: ..." line the page shows under it ("" when it succeeds)


def recipe_blocks(text: str) -> list[Block]:
    """The page's python blocks that name where they go, in page order."""
    out = []
    for body in re.findall(r"```python\n(.*?)```", text, flags=re.S):
        first, _, rest = body.partition("\n")
        m = _PLACE.match(first)
        if m is not None:
            out.append(Block(m["path"], m["how"] or "new", m["name"] or "", rest if m["how"] else body))
    return out


def recipe_commands(text: str) -> list[Command]:
    """The ``$`` lines of the page's text blocks, each with the error line shown under it (if any)."""
    out: list[Command] = []
    for body in re.findall(r"```text\n(.*?)```", text, flags=re.S):
        for line in body.splitlines():
            if line.startswith("$ "):
                out.append(Command(line[2:], ""))
            elif line.startswith("shm: error:") and out:
                out[-1] = Command(out[-1].line, line)
    return out


def place(tree: Path, block: Block) -> Path:
    """Write ``block`` into the copy where its first line says; the file it wrote or changed."""
    target = tree / block.path
    if block.how == "new":
        assert not target.exists(), f"the recipe's new file {block.path} exists already"
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(block.code, encoding="utf-8")
        return target
    lines = target.read_text(encoding="utf-8").splitlines(keepends=True)
    starts = [i for i, ln in enumerate(lines) if re.match(rf"^(?:def |class )?{block.name}\b", ln)]
    assert starts, f"{block.path} has no '{block.name}' for the recipe block to go {block.how}"
    at = starts[0]
    if block.how == "in" and lines[at].startswith("class "):  # after the class body's last line
        at = next((i for i in range(at + 1, len(lines)) if lines[i].strip() and not lines[i][0].isspace()),
                  len(lines))
        while not lines[at - 1].strip():
            at -= 1
        new = block.code
    elif block.how == "in":
        at = next(i for i in range(at + 1, len(lines)) if lines[i].rstrip() in (")", "}", "]"))
        new = block.code
    else:  # above NAME and the comment lines that document it
        while at > 0 and lines[at - 1].startswith("#"):
            at -= 1
        new = block.code.rstrip("\n") + "\n\n\n"
    target.write_text("".join(lines[:at]) + new + "".join(lines[at:]), encoding="utf-8")
    return target


def _tracked_files() -> list[str]:
    done = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True)
    return [f for f in done.stdout.decode().split("\0") if f]


def _run(tree: Path, argv: list[str]) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(tree), "MPLBACKEND": "Agg"}
    return subprocess.run(argv, cwd=tree, env=env, capture_output=True, text=True, timeout=_TIMEOUT_S)


@pytest.fixture(scope="module")
def newcomer_tree(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Path]]:
    """A copy of the repository's tracked files with every recipe block placed; (root, files written or changed)."""
    tree = tmp_path_factory.mktemp("fresh_clone")
    for rel in _tracked_files():
        src = ROOT / rel
        if src.is_file():
            (tree / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, tree / rel)
    if (ROOT / ".mypy_cache").is_dir():  # a warm cache (same files, same times) keeps mypy to seconds
        shutil.copytree(ROOT / ".mypy_cache", tree / ".mypy_cache")
    changed = [place(tree, b) for b in recipe_blocks(DOC.read_text(encoding="utf-8"))]
    return tree, sorted(set(changed))


def test_the_page_has_every_recipe_with_its_place():
    text = DOC.read_text(encoding="utf-8")
    places = {(b.path, b.how) for b in recipe_blocks(text)}
    assert {("plant/effects/tip_support.py", "new"), ("my_rig/tip_cable.py", "new"), ("drivers/can_link.py", "new"),
            ("drivers/hardware_links.py", "before"), ("drivers/hardware_links.py", "in"),
            ("studies/step_response/__init__.py", "new"), ("studies/step_response/setup.py", "new"),
            ("studies/step_response/run.py", "new"), ("shm_cli/step_cmd.py", "new"),
            ("shm_cli/main.py", "in"), ("workbench/records/_npz_format.py", "new"),
            ("workbench/records/_io.py", "before"),
            ("workbench/records/_io.py", "in"), ("tests/workbench/test_record_npz.py", "new"),
            ("firmware_sim/regimes.py", "in"), ("firmware_sim/regimes.py", "before"),
            ("tests/firmware_sim/test_regime_overrun_cooled.py", "new")} <= places
    assert {b.name for b in recipe_blocks(text) if b.path == "firmware_sim/regimes.py"} == {"Trigger", "TRANSITIONS"}
    commands = [c.line.split()[:2] for c in recipe_commands(text)]
    for wanted in (["shm", "effects"], ["pytest", "-q"], ["shm", "synth"], ["shm", "run"], ["shm", "step"]):
        assert wanted in commands, wanted
    assert any("tests/firmware_sim/test_regime_overrun_cooled.py" in c.line for c in recipe_commands(text))


def test_place_puts_a_table_entry_after_the_last_and_a_function_above_its_table(tmp_path):
    (tmp_path / "m.py").write_text('A = 1\n\n\n#: the table\nTABLE: dict[str, int] = {\n    "a": 1,\n}\n')
    place(tmp_path, Block("m.py", "in", "TABLE", '    "b": 2,\n'))
    place(tmp_path, Block("m.py", "before", "TABLE", "def f() -> int:\n    return 2\n"))
    assert (tmp_path / "m.py").read_text() == ('A = 1\n\n\ndef f() -> int:\n    return 2\n\n\n#: the table\n'
                                               'TABLE: dict[str, int] = {\n    "a": 1,\n    "b": 2,\n}\n')


def test_place_puts_a_class_member_after_the_last(tmp_path):
    (tmp_path / "m.py").write_text('class K(StrEnum):\n    A = "a"\n\n    B = "b"  # b\n\n\nX = 1\n')
    place(tmp_path, Block("m.py", "in", "K", '    C = "c"\n'))
    assert (tmp_path / "m.py").read_text() == ('class K(StrEnum):\n    A = "a"\n\n    B = "b"  # b\n    C = "c"\n'
                                               '\n\nX = 1\n')


def test_the_copy_imports_its_own_packages(newcomer_tree):
    tree, _ = newcomer_tree
    done = _run(tree, [sys.executable, "-c", "import plant, shm_cli; print(plant.__file__)"])
    assert done.returncode == 0, done.stderr  # before issue 30: a circular import from plant/effects/tip_support.py
    assert Path(done.stdout.strip()).is_relative_to(tree)


def test_ruff_and_mypy_accept_the_recipes(newcomer_tree):
    tree, changed = newcomer_tree
    files = [str(p.relative_to(tree)) for p in changed]
    ruff = _run(tree, [str(BIN / "ruff"), "check", *files])
    assert ruff.returncode == 0, ruff.stdout + ruff.stderr
    mypy = _run(tree, [str(BIN / "mypy"), *files])
    assert mypy.returncode == 0, mypy.stdout + mypy.stderr


@pytest.mark.parametrize("command", recipe_commands(DOC.read_text(encoding="utf-8")), ids=lambda c: c.line)
def test_the_recipe_commands_run(newcomer_tree, command):
    tree, _ = newcomer_tree
    argv = shlex.split(command.line)
    tool = {"shm": _SHM, "pytest": [str(BIN / "pytest")]}.get(argv[0])
    assert tool is not None, f"the page runs '{argv[0]}': teach this test how"
    done = _run(tree, [*tool, *argv[1:]])
    said = done.stdout + done.stderr
    if command.error:
        assert done.returncode == 2, said
        assert command.error in done.stderr.splitlines(), said
    else:
        assert done.returncode == 0, said
        assert "Traceback" not in said and "internal error" not in said, said
        if "--out" in argv:  # what it wrote is where the page said
            out = tree / argv[argv.index("--out") + 1]
            assert out.is_file() or any(out.iterdir()), f"{command.line}: nothing written to {out}"
