"""Figures checked as pictures (issue 27.4): every figure the CLI writes is rendered and checked for overlapping
text, text cut off, a legend over the data, nan/inf printed and fractional ticks on a count axis
(:mod:`reporting.figure_legibility`); every HTML report is opened in headless Chromium and must show its images.

One module fixture runs each figure-writing command once on tiny inputs, with a hook on
:func:`reporting.figures.save_figure` (the one place figures are saved) that checks each figure just before it is
written. A PNG in an output folder that did not pass the hook fails too: no figure escapes the check.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.image import imread
from scenario_text_support import gust, life_scenario, linear_law, phases

from reporting.figure_layout import count_axis, few_ticks, hide_colliding_texts, legend_clear_of_data
from reporting.figure_legibility import Finding, check_figure, describe
from reporting.figures import observing_saved_figures, pyplot
from shm_cli.main import main

# ------------------------------------------------------------------------------------------------------------------
# the checker on figures with one known fault each (fast), and the placement helpers that clear them


def _kinds(fig: Any, lay_out: bool = False) -> set[str]:
    """The kinds of finding on ``fig`` (after ``tight_layout`` with ``lay_out``); the figure is closed."""
    if lay_out:
        fig.tight_layout()
    found = {f.kind for f in check_figure(fig)}
    pyplot().close(fig)
    return found


def _axes(figsize: tuple[float, float] = (5, 3)) -> tuple[Any, Any]:
    fig, ax = pyplot().subplots(figsize=figsize)
    return fig, ax


def _diagonal() -> tuple[Any, Any]:
    """Axes holding one line from (0, 0) to (1, 1): a plain figure to put texts on."""
    fig, ax = _axes()
    ax.plot([0, 1], [0, 1])
    return fig, ax


def test_a_plain_figure_has_no_findings() -> None:
    fig, ax = _axes()
    ax.plot(np.linspace(0, 1, 50), np.linspace(0, 1, 50) ** 2, label="data")
    ax.set_xlabel("time (s)")
    ax.set_title("plain")
    ax.legend(loc="upper left")
    assert _kinds(fig, lay_out=True) == set()


def test_overlapping_and_crowded_texts_are_found_and_named() -> None:
    fig, ax = _diagonal()
    ax.text(0.5, 0.5, "first label")
    ax.text(0.5, 0.5, "second label")
    found = check_figure(fig)
    assert any(f.kind == "text overlap" and "'first label'" in f.detail and "'second label'" in f.detail
               for f in found)
    pyplot().close(fig)
    fig, ax = _axes((3, 2))  # "596.0596.5...": long tick labels in a narrow panel
    t = np.linspace(596, 600, 400)
    ax.plot(t, np.sin(t))
    ax.set_xticks(np.arange(596, 600.01, 0.5))
    assert "text overlap" in _kinds(fig, lay_out=True)
    fig, ax = _axes((3, 2))
    ax.plot(t, np.sin(t))
    few_ticks(ax.xaxis, 4)
    assert _kinds(fig, lay_out=True) == set()


def test_text_outside_the_figure_and_non_finite_numbers_are_found() -> None:
    fig, ax = _diagonal()
    fig.text(0.98, 0.5, "a long note running off the edge")
    ax.text(0.2, 0.2, "+nan %, ΔBIC -inf")
    assert _kinds(fig) == {"text outside the figure", "non-finite number"}


def test_a_legend_over_the_data_is_found_and_head_room_clears_it() -> None:
    t = np.linspace(0, 1, 200)
    fig, ax = _axes()
    ax.plot(t, t, label="rising to the top right corner")
    ax.legend(loc="upper right")
    assert _kinds(fig) == {"legend covers data"}
    fig, ax = _axes()
    ax.plot(t, t, label="rising to the top right corner")
    fig.tight_layout()
    legend_clear_of_data(ax)
    assert _kinds(fig) == set()


def test_bars_over_bars_are_found_and_side_by_side_bars_pass() -> None:
    y = np.arange(3)
    fig, ax = _axes()
    ax.barh(y, [1, 2, 3], label="before")
    ax.barh(y, [2, 1, 1], label="after")
    assert _kinds(fig) == {"bars hide each other"}
    fig, ax = _axes()
    ax.barh(y + 0.2, [1, 2, 3], height=0.4, label="before")
    ax.barh(y - 0.2, [2, 1, 1], height=0.4, label="after")
    assert _kinds(fig) == set()
    fig, ax = _axes()  # the tallest bar's top under the legend
    ax.bar(y, [1, 2, 3], label="counts")
    ax.legend(loc="upper right")
    assert _kinds(fig) == {"legend covers data"}


def test_fractional_ticks_on_a_count_axis_are_found_and_integer_ticks_pass() -> None:
    fig, ax = _axes()
    ax.plot([0, 1, 2], [3.0, 2.0, 1.5], "o-")
    ax.set_xlabel("iteration")
    assert _kinds(fig, lay_out=True) == {"fractional ticks on a count axis"}
    fig, ax = _axes()
    ax.plot([0, 1, 2], [3.0, 2.0, 1.5], "o-")
    count_axis(ax.xaxis)
    assert _kinds(fig) == set()


def test_colliding_labels_are_hidden_most_important_kept() -> None:
    fig, ax = _diagonal()
    big, small, apart = ax.text(0.5, 0.5, "58%"), ax.text(0.5, 0.5, "26%"), ax.text(0.1, 0.9, "16%")
    fig.canvas.draw()
    assert hide_colliding_texts([big, small, apart]) == [big, apart] and not small.get_visible()
    assert _kinds(fig) == set()


ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("board_config", "plant", "firmware_sim", "drivers", "hil_stub", "reporting", "workbench", "studies",
            "shm_cli")


def test_figures_are_written_only_by_save_figure() -> None:
    """``savefig`` is called in one place, ``reporting.figures.save_figure``, whose hook the figure tests use: a
    figure saved any other way would escape the check."""
    callers = [f"{p.relative_to(ROOT)}:{i}" for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))
               for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), start=1)
               if re.search(r"\.savefig\(|imsave\(|print_png\(", line)]
    assert callers and all(c.startswith("reporting/figures.py:") for c in callers), callers


# ------------------------------------------------------------------------------------------------------------------
# every figure the CLI writes (slow: one module fixture runs each command once)

SHORT_RUN = ("""
[scenario]
name = "figures-short"
seed = 2
expect_verdict = "PASS"

[rig]
params = "table2"

[board.sensing]
quiet_period = { value = 1.0, unit = "s" }

[board.maintenance]
settle = { value = 0.2, unit = "s" }
hv_debounce = { value = 0.1, unit = "s" }

""" + phases(("flight", "3.0", "", 'vibration_rms = { value = 0.5, unit = "m/s^2" }\n'), ("maintenance", "24.5"),
             ("ground", "0.5"), sep="\n") + "\n" + gust("0.5", "12.0", "0.5"))

#: a short life (docs/scenarios.md [life]): 8 visits 200 h apart, the monitor's first FAULT at about 1200 h, so that
#: shm health --evaluate has the visits before it to score
SHORT_LIFE = "\n" + life_scenario(
    "figures-life", 8, 200, seed=1, rig='params = "table2"\nbattery_initial_voltage = { value = 3.0, unit = "V" }\n',
    more_life='first_visit = { value = 0, unit = "h" }\nflights_between_visits = { value = 2, unit = "1" }\n',
    laws=(linear_law("k3", "-2.0e-4"),
          '[[life.law]]\nparameter = "alpha_h"\nkind = "power"\namplitude = { value = 0.15, unit = "1" }\n'
          'reference = { value = 1200, unit = "h" }\nexponent = { value = 1.5, unit = "1" }\n'),
    visit=(("ground", "1"), ("maintenance", "30"), ("ground", "1")), sep="\n")


@dataclass
class Drawn:
    """What the hook saw: every saved figure's findings (a live figure is saved and checked several times), by
    command, and the output folder of each command."""

    findings: dict[str, list[tuple[Path, list[Finding]]]] = field(default_factory=dict)
    outputs: dict[str, Path] = field(default_factory=dict)
    exit_codes: dict[str, int] = field(default_factory=dict)


def _synth(tmp: Path, name: str, *args: str) -> Path:
    path = tmp / name
    assert main(["synth", "--params", "table2", "--seed", "7", "--out", str(path), *args]) == 0
    return path


def _commands(tmp: Path) -> dict[str, list[str]]:
    """The figure-writing commands on tiny inputs: command -> argv (its --out is tmp/command)."""
    stiffening = ("--effect", "geometric_stiffening", "--set", "kappa_nl=2e4", "--noise", "z3=2e-6")
    stiff = _synth(tmp, "stiff.csv", "--test", "mbit-b", *stiffening)
    loop = _synth(tmp, "loop.csv", "--test", "mbit-a", *stiffening)  # its residual trough sat under the legend
    sweep = _synth(tmp, "sweep.csv", "--test", "sweep", *stiffening)
    frf = _synth(tmp, "frf.csv", "--test", "frf", "--f0-hz", "5", "--f1-hz", "30", "--n-freqs", "8")
    scenario = tmp / "short.toml"
    scenario.write_text(SHORT_RUN)
    life = tmp / "life.toml"
    life.write_text(SHORT_LIFE)
    return {
        "compare": ["compare", str(loop), str(sweep), str(frf), "--params", "table2"],
        "diagnose": ["diagnose", str(stiff), "--params", "table2", "--candidates",
                     "geometric_stiffening,dielectric_leakage,piezo_creep,k3,m3", "--fit-top", "1"],
        "fit": ["fit", str(stiff), "--params", "table2", "--add", "geometric_stiffening",
                "--save", str(tmp / "fitted.toml")],
        "calibrate": ["calibrate", "--params", "table2", "--free", "k3", "--save", str(tmp / "cal.toml")],
        "model frf": ["model", "frf", "--points", "200"],
        "model step": ["model", "step", "--duration-s", "0.5"],
        "model loop": ["model", "loop", "--freq-hz", "0.5", "--cycles", "1"],
        "harvest": ["harvest", "--params", "table2"],
        "campaign": ["campaign", "--mbit", "both", "--ranges", "0:50:10", "--n", "3", "--seed", "1", "--workers", "1",
                     "--no-progress"],
        "campaign-roc": ["campaign-roc", "--from", str(tmp / "campaign"), "--eps-th", "0.1:0.3:0.1", "--count-max",
                         "100,200"],
        "run": ["run", "--scenario", str(scenario), "--timeline-every-s", "0", "--quiet"],
        "run life": ["run", "--scenario", str(life), "--quiet"],
        "health": ["health", str(tmp / "run_life"), "--params", "table2", "--evaluate", "--workers", "1",
                   "--locate", "never"],
    }


@pytest.fixture(scope="module")
def drawn(tmp_path_factory: pytest.TempPathFactory) -> Drawn:
    tmp = tmp_path_factory.mktemp("figures")
    result = Drawn()
    current: list[str] = [""]

    def check(fig: Any, path: Path) -> None:
        try:
            found = check_figure(fig)
        except Exception as exc:  # the commands catch a figure's failure: keep it as a finding instead
            found = [Finding("checker failed", f"{type(exc).__name__}: {exc}")]
        result.findings.setdefault(current[0], []).append((path, found))

    commands = _commands(tmp)
    with observing_saved_figures(check):
        for name, argv in commands.items():
            current[0] = name
            out = tmp / name.replace(" ", "_")
            result.outputs[name] = out
            result.exit_codes[name] = main([*argv, "--out", str(out)])
    return result


COMMANDS = ("compare", "diagnose", "fit", "calibrate", "model frf", "model step", "model loop", "harvest",
            "campaign", "campaign-roc", "run", "run life", "health")


@pytest.mark.slow
@pytest.mark.parametrize("command", COMMANDS)
def test_every_figure_reads(drawn: Drawn, command: str) -> None:
    """The command's figures: no overlapping or cut-off text, no legend over the data, no nan/inf, whole-number
    ticks on count axes; and every PNG it wrote passed the check."""
    assert drawn.exit_codes[command] == 0, command
    seen = drawn.findings.get(command, [])
    # by file name: life and health draw into a staging folder and move the finished files into --out
    written = {p.name for p in drawn.outputs[command].rglob("*.png")}
    checked = {Path(p).name for p, _ in seen}
    assert written, f"{command} wrote no figure"
    assert written <= checked, f"figures written without reporting.figures.save_figure: {sorted(written - checked)}"
    bad = [describe(p.name, f) for p, f in seen if f]
    assert not bad, "\n".join(bad)


# ------------------------------------------------------------------------------------------------------------------
# the HTML reports in headless Chromium (Debian's ``chromium``; ``make system-packages`` installs it)

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
needs_chromium = pytest.mark.skipif(CHROMIUM is None, reason="chromium not installed (make system-packages as root "
                                                             "installs it): the HTML reports are not screenshot")
#: after the page's load event, each <img>'s (complete, naturalWidth, naturalHeight) onto <body data-images>
_PROBE = ("<script>window.addEventListener('load', () => document.body.setAttribute('data-images', JSON.stringify("
          "Array.from(document.images).map(i => [i.complete, i.naturalWidth, i.naturalHeight]))));</script>")


def _chromium(args: list[str], tmp: Path) -> str:
    r = subprocess.run([str(CHROMIUM), "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                        "--hide-scrollbars", f"--user-data-dir={tmp / 'profile'}", *args],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    return r.stdout


def image_sizes(page: Path, tmp: Path) -> list[tuple[bool, int, int]]:
    """(complete, naturalWidth, naturalHeight) of every <img> of ``page`` as Chromium decoded it."""
    text = page.read_text(encoding="utf-8")
    probe = tmp / f"probe_{page.stem}.html"
    probe.write_text(text.replace("</body>", _PROBE + "</body>") if "</body>" in text else text + _PROBE,
                     encoding="utf-8")
    dom = _chromium(["--dump-dom", probe.as_uri()], tmp)
    m = re.search(r'data-images="([^"]*)"', dom)
    assert m, f"{page.name}: the page's load event never came (no data-images in the DOM)"
    return [tuple(x) for x in json.loads(m.group(1).replace("&quot;", '"'))]


def drawn_share(page: Path, tmp: Path) -> float:
    """Share of a 1280×2400 screenshot's pixels that differ from its most common colour (the background)."""
    shot = tmp / f"shot_{page.stem}.png"
    _chromium([f"--screenshot={shot}", "--window-size=1280,2400", page.as_uri()], tmp)
    px = (imread(shot)[..., :3] * 255).astype(np.uint8).reshape(-1, 3)
    _, counts = np.unique(px, axis=0, return_counts=True)
    return 1.0 - counts.max() / px.shape[0]


REPORTS = (("compare", "report.html"), ("diagnose", "diagnosis.html"), ("fit", "fit.html"), ("health", "report.html"),
           ("run", "report.html"), ("run life", "report.html"))


@pytest.mark.slow
@needs_chromium
@pytest.mark.parametrize(("command", "page"), REPORTS)
def test_html_report_renders_with_its_images(drawn: Drawn, command: str, page: str,
                                             tmp_path: Path) -> None:
    """The report opens in Chromium, every <img> decodes (naturalWidth > 0) and the screenshot is not blank."""
    path = drawn.outputs[command] / page
    n_tags = path.read_text(encoding="utf-8").count("<img")
    sizes = image_sizes(path, tmp_path)
    assert n_tags > 0 and len(sizes) == n_tags, (n_tags, sizes)
    broken = [i for i, (complete, w, h) in enumerate(sizes) if not (complete and w > 0 and h > 0)]
    assert not broken, f"{page} of {command}: images {broken} do not decode ({sizes})"
    assert drawn_share(path, tmp_path) > 0.05, f"{page} of {command}: the screenshot is (nearly) blank"


@pytest.mark.slow
@needs_chromium
def test_the_html_probes_see_a_broken_image_and_a_blank_page(tmp_path: Path) -> None:
    """The two probes can fail: a corrupt embedded PNG does not decode, an empty page screenshots blank."""
    page = tmp_path / "broken.html"
    page.write_text("<!DOCTYPE html><html><body><h1>report</h1><img src='data:image/png;base64,iVBORw0KGgoAAAA'>"
                    "</body></html>")
    assert [w for _, w, _ in image_sizes(page, tmp_path)] == [0]
    blank = tmp_path / "blank.html"
    blank.write_text("<!DOCTYPE html><html><body></body></html>")
    assert drawn_share(blank, tmp_path) < 0.001
