"""`shm effects list|show` (issue 27, point 6): the effects a user can add, each with its parameters (SI unit,
default, bounds), neutral values, fit ranges and what it models — by registered name, dotted path or file, as
``--effect`` takes them. The values printed are the classes' own declarations (checked against them, not against
copies), and the docs' recipe (docs/effects.md, "Seeing the effects") runs here."""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import pytest

from plant import resolve_effect
from plant.effect import library_effects, registered_effects
from shm_cli.main import main

DOCS = Path(__file__).parents[2] / "docs" / "effects.md"


def _json(capsys, argv: list[str]) -> dict:
    assert main(argv) == 0
    out = capsys.readouterr().out
    return json.loads(out)  # exactly one JSON document on stdout


def test_list_names_every_library_effect_and_all_adds_the_core(capsys):
    assert main(["effects", "list"]) == 0
    out = capsys.readouterr().out
    for name in library_effects():
        assert re.search(rf"^  {name}\s", out, re.M), name
    assert "kappa_nl [m^-2]" in out and "laminate" not in out
    doc = _json(capsys, ["effects", "list", "--all", "--json"])
    names = [e["name"] for e in doc["effects"]]
    assert set(names) == set(registered_effects()) and names[:len(library_effects())] == list(library_effects())
    roles = {e["name"]: e["role"] for e in doc["effects"]}
    assert roles["laminate"] == "core" and roles["amplifier"] == "terminal"


def test_show_geometric_stiffening(capsys):
    assert main(["effects", "show", "geometric_stiffening"]) == 0
    out = capsys.readouterr().out
    assert "kappa_nl [m^-2]" in out and "neutral 0" in out
    assert "fit range [-10000, 200000] symlog within ±100, declared by the effect; fitted by default" in out
    assert "von Kármán" in out  # what it models (origin) ...
    assert "odd harmonics" in out  # ... and what its absence leaves in residuals
    d = _json(capsys, ["effects", "show", "geometric_stiffening", "--json"])
    (p,) = d["parameters"]
    assert (p["name"], p["unit"], p["default"], p["neutral"]) == ("kappa_nl", "m^-2", 0.0, 0.0)
    assert (p["lower"], p["upper"]) == (-1e4, 5e5)
    assert p["fit"] == {"lower": -1e4, "upper": 2e5, "scale": "symlog", "linthresh": 100.0,
                        "source": "declared by the effect"}


@pytest.mark.parametrize("name", sorted(registered_effects()))
def test_show_matches_every_effects_declarations(name, capsys):
    cls = resolve_effect(name)
    d = _json(capsys, ["effects", "show", name, "--json"])
    assert d["role"] == cls.role and d["description"] == cls.description
    assert [p["name"] for p in d["parameters"]] == [p.name for p in cls.parameters]
    for p, par in zip(d["parameters"], cls.parameters):
        assert p["unit"] == par.unit
        if par.core_index is not None:
            assert p["fit"] is None
            continue
        assert p["default"] == par.default
        assert p["neutral"] == par.neutral
        assert p["fit"]["lower"] < p["fit"]["upper"]


def test_show_by_dotted_path_file_and_instance(tmp_path, capsys):
    d = _json(capsys, ["effects", "show", "plant.effects.geometric_stiffening:GeometricStiffening", "--json"])
    assert d["name"] == "geometric_stiffening"
    f = tmp_path / "tip_spring.py"
    f.write_text(_docs_block("python", "# my_effects.py"))
    assert main(["effects", "show", str(f)]) == 0
    out = capsys.readouterr().out
    assert "tip_support (effect)" in out and "k_tip [N/m]" in out and f"file {f}" in out
    assert "neutral none declared" in out and "derived from the bounds" in out
    d = _json(capsys, ["effects", "show", "laser_sensor as ls2", "--json"])
    assert [p["name"] for p in d["parameters"]] == ["ls2.z_offset", "ls2.spot_offset", "ls2.tau_sensor"]


def test_bad_names_are_one_clear_line(capsys, tmp_path):
    for argv, needle in ((["effects", "show", "warp"], "unknown effect 'warp'"),
                         (["effects", "show", str(tmp_path / "none.py")], "none.py"),
                         (["effects", "show", "os:path"], "not a PhysicalEffect")):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert needle in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def _docs_block(lang: str, marker: str) -> str:
    text = DOCS.read_text()
    blocks = re.findall(rf"```{lang}\n(.*?)```", text, re.S)
    found = [b for b in blocks if marker in b]
    assert found, f"docs/effects.md lost its {lang} block with {marker!r}"
    return found[0]


def test_the_docs_recipe_runs(capsys):
    block = _docs_block("sh", "shm effects list")
    commands = [ln.split("#", 1)[0].strip() for ln in block.splitlines() if ln.strip().startswith("shm ")]
    assert len(commands) >= 3
    for cmd in commands:
        assert main(shlex.split(cmd)[1:]) == 0, cmd
        capsys.readouterr()
