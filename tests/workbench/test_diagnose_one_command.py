"""Issue 26 point 2: one command to the answer. When the library and the core parameters fall short, ``shm diagnose``
runs the discovery step itself and ends with one verdict — what was found in words and formula, the emitted effect
file (inside --out, never over an existing file) and the ``shm fit … --add FILE`` command; ``--no-discover`` opts
out; ``--json`` carries the same in its ``discover`` section. The slow tests run the command on a record whose truth
is outside the library (free play in the root clamp, tests/workbench_foreign_effects.py)."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import pytest

from workbench.diagnose._discovery import damage_cure, falls_short, final_verdict, new_effect_file

FOREIGN = (Path(__file__).parents[1] / "workbench_foreign_effects.py")


def test_the_effect_file_never_overwrites(tmp_path):
    (tmp_path / "discovered.py").write_text("# mine\n")
    a = new_effect_file(tmp_path)
    b = new_effect_file(tmp_path)
    assert a.name == "discovered_2.py" and b.name == "discovered_3.py"
    assert (tmp_path / "discovered.py").read_text() == "# mine\n"


def test_falls_short_is_the_verdict_saying_so():
    assert falls_short(SimpleNamespace(verdict="partial")) and falls_short(SimpleNamespace(verdict="unexplained"))
    for v in ("wrong_parameter", "missing", "combination", "nothing_missing"):
        assert not falls_short(SimpleNamespace(verdict=v))


def _disc(held_after, terms=("section 1 is softer within ±40 µm of δ1",)):
    return SimpleNamespace(terms=[SimpleNamespace(description=t, said_with="") for t in terms], held_before=8.6,
                           held_after=held_after, message="Found: …", verdict="found")


def _found(placements, held_after=1.02, verdict="found"):
    return SimpleNamespace(terms=[SimpleNamespace(term=SimpleNamespace(placement=p)) for p in placements],
                           held_after=held_after, verdict=verdict, timings={"total_s": 17.0})


def test_only_a_cure_of_damage_forms_ends_the_library_search_early():
    """Issue 26 point 7: after the greedy path the beam is skipped only for a cure made of damage forms — a cubic
    stiffness or a leakage current found beyond the library may be a library effect's twin."""
    assert damage_cure(_found(["damage"])) and damage_cure(_found(["damage", "damage"], 1.4, "partial"))
    assert not damage_cure(_found(["damage", "force_section"]))  # a twin of geometric stiffening may hide there
    assert not damage_cure(_found(["damage"], 2.5, "partial")) and not damage_cure(_found([]))


@pytest.mark.parametrize("changed", [False, True])
def test_the_discovery_run_before_the_beam_is_not_run_again(monkeypatch, tmp_path, changed):
    """The same records, the same parameter set: the early run stands — unless the library's named set changed
    during the record, when the discovery runs again, told to expect a change."""
    import workbench.diagnose._discovery as dd

    runs: list[bool] = []
    early, late = _found(["damage"]), _found(["damage"])
    monkeypatch.setattr(dd, "run_discovery", lambda *a, expect_change=False, **kw: runs.append(expect_change) or late)
    seen: list[object] = []
    monkeypatch.setattr(dd, "write_emitted", lambda disc, directory: (None, "not here"))
    monkeypatch.setattr(dd, "final_verdict", lambda d, disc, section: seen.append(disc))
    monkeypatch.setattr(dd, "discovery_section", lambda disc, **kw: {"ran": True})
    d = SimpleNamespace(verdict="partial", time_change=SimpleNamespace(changed=changed), timings={}, message="")
    dd.discovery_step(d, [], "table2", "table2", tmp_path, holdout="blocks", n_blocks=5, max_rate_Hz=250.0,
                      early=early)
    assert (runs, seen) == (([True], [late]) if changed else ([], [early]))


def test_the_final_verdict_leads_with_what_was_found(monkeypatch):
    import workbench.diagnose._discovery as dd

    monkeypatch.setattr(dd, "term_formulas", lambda disc: ["S_1 += c · clip(δ1, g)"])
    d = SimpleNamespace(message="The library and the core parameters explain only 96 % of the excess over the noise: "
                                "…\nLook for the rest beyond the library:\n  shm discover …",
                        winner=SimpleNamespace(held_rms_sigma=1.89), baseline_held_rms_sigma=8.6, verdict="partial",
                        fit_command="", next_command="shm discover …")
    section = {"emitted": {"file": "out/discovered.py", "effect": "discovered_discovered", "class": "C"},
               "fit_command": "shm fit rec.csv --params table2 --add out/discovered.py --save refit.toml --out fit"}
    final_verdict(d, _disc(1.05), section)
    first, rest = d.message.split("\n", 1)
    assert first.startswith("Found beyond the library: section 1 is softer")
    assert "Formula: S_1 += c · clip(δ1, g)" in first and "out/discovered.py" in first
    assert "explain only 96 %" in rest and "shm discover" not in d.message  # one verdict: the step ran
    assert d.message.rstrip().endswith(section["fit_command"]) and d.verdict == "discovered"
    assert d.fit_command == section["fit_command"]


def test_terms_short_of_a_cure_are_named_as_a_part_with_their_share_not_as_a_finding(monkeypatch):
    import workbench.diagnose._discovery as dd

    monkeypatch.setattr(dd, "term_formulas", lambda disc: ["K_3 *= 1 - a·[t > t0]"])
    d = SimpleNamespace(message="The library and the core parameters explain only 60 % …\nLook …",
                        verdict="unexplained",
                        winner=None, baseline_held_rms_sigma=565.0, fit_command="", next_command="x")
    lost = "section 3 lost 11.1 % of its stiffness at t = 0.73 s"
    disc = SimpleNamespace(terms=[SimpleNamespace(description=lost, said_with="")],
                           held_before=565.0, held_after=91.2, message="Partly found: …", verdict="partial")
    final_verdict(d, disc, {"emitted": None, "fit_command": ""})
    first = d.message.split("\n", 1)[0].split(". ", 1)[0]
    assert first.startswith("Explained only in part") and "Found" not in first
    assert "section 3 lost 11.1 %" in first and "91.2 σ of 565 σ" in first
    assert "97 % of the excess over the noise" in first  # 1 − (91.2² − 1)/(565² − 1)
    assert d.verdict == "partly_discovered"
    assert dd.excess_share(8.6, 1.0) == 1.0 and dd.excess_share(1.0, 3.0) == 0.0


def test_a_discovery_no_better_than_the_library_follows_it(monkeypatch):
    import workbench.diagnose._discovery as dd

    monkeypatch.setattr(dd, "term_formulas", lambda disc: ["…"])
    d = SimpleNamespace(message="The library and the core parameters explain only 96 % …\nLook …", verdict="partial",
                        winner=SimpleNamespace(held_rms_sigma=1.89), baseline_held_rms_sigma=8.6, fit_command="",
                        next_command="x")
    final_verdict(d, _disc(3.0), {"emitted": None, "fit_command": ""})
    assert d.message.startswith("The library and the core parameters explain only 96 %")
    assert "The discovery step ran too: Found: …" in d.message and d.verdict == "partial"


def _synth(tmp_path, kind="mbit-b"):
    from shm_cli.main import main

    rec = tmp_path / "play.csv"
    assert main(["synth", "--test", kind, "--effect", f"{FOREIGN}:RootClearance", "--set", "k_play=150",
                 "--set", "g_play=4e-5", "--seed", "3", "--out", str(rec)]) == 0
    return rec


@pytest.mark.slow
def test_one_command_finds_free_play_and_says_how_to_fit_it(tmp_path, capsys):
    from shm_cli.main import main

    rec = _synth(tmp_path)
    capsys.readouterr()
    out = tmp_path / "d"
    assert main(["diagnose", str(rec), "--params", "table2", "--out", str(out), "--json"]) == 0
    cap = capsys.readouterr()
    result = json.loads(cap.out)  # one JSON document on stdout
    first = result["message"].split("\n", 1)[0]
    assert first.startswith("Found beyond the library: section 1"), first
    assert "beta_h" not in first and "re-estimate it" not in result["message"]
    disc = result["discover"]
    assert disc["ran"] and disc["emitted"] and disc["formulas"]
    emitted = Path(disc["emitted"]["file"])
    assert emitted.parent == out and emitted.exists()
    assert disc["fit_command"] == f"shm fit {rec} --params table2 --add {emitted} --save refit.toml --out fit"
    assert disc["fit_command"] in result["message"] and result["fit_command"] == disc["fit_command"]
    assert disc["held_rms_sigma"]["after"] <= 1.5
    assert "Found beyond the library" in cap.err  # the text goes to stderr
    # the command it prints works: the emitted effect refits to the noise floor
    capsys.readouterr()
    argv = [*disc["fit_command"].split()[1:], "--json"]
    argv[argv.index("--out") + 1] = str(tmp_path / "fit")
    argv[argv.index("--save") + 1] = str(tmp_path / "refit.toml")
    assert main(argv) == 0
    fit = json.loads(capsys.readouterr().out)
    assert fit["held_rms_sigma"]["after"] <= 1.5


@pytest.mark.slow
def test_no_discover_leaves_the_command_to_the_user(tmp_path, capsys):
    from shm_cli.main import main

    rec = _synth(tmp_path)
    capsys.readouterr()
    out = tmp_path / "d"
    assert main(["diagnose", str(rec), "--params", "table2", "--out", str(out), "--json", "--no-discover"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["discover"] == {"ran": False, "reason": "--no-discover", "seconds": 0.0}
    assert result["message"].startswith("The library and the core parameters explain only ")
    assert "shm discover" in result["next_command"] and not list(out.glob("*.py"))
