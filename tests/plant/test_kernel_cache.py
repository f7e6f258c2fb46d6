"""The compile announcement's words, its routing, the cold-cache check that compiles nothing, and the shipped
compositions ``make setup`` builds (plant.kernel_cache, plant.compose.uncached_entries, plant.warm; issue 27.1)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

from plant import PlantModel
from plant.compose import KERNEL_ENTRIES
from plant.effect import library_effects
from plant.kernel_cache import announce_compile, compile_message, composition_words, set_announcer
from plant.warm import MEMBER_ENTRIES, NO_HYSTERESIS, shipped_compositions


def test_the_announcement_names_the_effects_and_terminal_and_says_it_is_a_first_use():
    assert composition_words(PlantModel("table2").effects) == ("the nominal model (amplifier terminal)", 0)
    words, n = composition_words(PlantModel("table2", effects=["dielectric_leakage", "piezo_creep"],
                                            terminal="open_circuit").effects)
    assert (words, n) == ("the model for effects dielectric_leakage, piezo_creep (open_circuit terminal)", 2)
    words, _ = composition_words(PlantModel("table2", terminal="harvest_paper", core=NO_HYSTERESIS).effects)
    assert words == "the nominal model (core laminate, patch_rc, piezo_coupling; harvest_paper terminal)"
    text = compile_message(words, "run_lanes", 41.6)
    assert text.startswith("compiling the nominal model") and "batch integrator (lanes)" in text
    assert "(first use, ~42 s; cached afterwards)" in text and text.endswith("…")


def test_the_announcement_goes_where_the_caller_routes_it():
    heard: list[str] = []
    previous = set_announcer(heard.append)
    try:
        announce_compile(PlantModel("table2", effects=["air_damping"]).effects)
    finally:
        assert set_announcer(previous) == heard.append
    assert len(heard) == 1 and heard[0].startswith("compiling the model for effects air_damping (amplifier terminal)")


def test_a_cold_cache_lists_every_entry_to_compile_without_compiling(tmp_path):
    code = ("import json, time; t = time.perf_counter(); from plant import PlantModel; "
            "m = PlantModel('table2'); u = m.uncached_kernels(); "
            "print(json.dumps([u, time.perf_counter() - t, m._kernel_module is None]))")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    env.pop("MFC_SHM_KERNEL_DIR", None)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    entries, seconds, not_built = json.loads(out.stdout)
    assert entries == list(KERNEL_ENTRIES) and not_built
    assert seconds < 8  # reading the index; a compile takes tens of seconds
    assert "compiling" not in out.stderr


def test_setup_builds_the_nominal_models_the_library_and_the_scenarios_once_each():
    comps = shipped_compositions()
    keys = [c.model().effect_names for c in comps]
    assert len(keys) == len(set(keys))  # one entry per composition (parameter values are not in a kernel)
    by = {k: c for k, c in zip(keys, comps)}
    nominal = ("laminate", "patch_rc", "bouc_wen", "piezo_coupling")
    assert by[(*nominal, "amplifier")].entries == KERNEL_ENTRIES  # fits and diagnose integrate batches in lanes
    assert by[(*NO_HYSTERESIS, "harvest_paper")].entries == MEMBER_ENTRIES
    for name in library_effects():
        assert "run_lanes" in by[(*nominal, "amplifier", name)].entries
        assert (*nominal, "open_circuit", name) in by
    assert (*nominal, "harvest_coupled", "dielectric_leakage") in by  # the patch_leakage scenario's rig in flight


def test_a_shell_without_numba_cache_dir_uses_the_cache_make_setup_filled(tmp_path):
    # make exports NUMBA_CACHE_DIR=~/.cache/mfc-shm/numba; a later `shm` typed in a plain shell must find the same
    code = "import plant, numba; from plant.compose import kernel_dir; print(numba.config.CACHE_DIR, kernel_dir())"
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "MFC_SHM_KERNEL_DIR")}
    env["HOME"] = str(tmp_path)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    want = tmp_path / ".cache" / "mfc-shm" / "numba"
    assert out.stdout.split() == [str(want), str(want / "kernels")]


def test_setup_builds_the_kernel_a_first_shm_discover_loads():
    # the dictionary's source depends on the terms' structure only: built from any record's scales, discover composes
    # the kernel module that workbench.warm compiled (same cache key, hence the same generated module)
    from workbench.discover import build_dictionary, dictionary_source, generated_effect
    from workbench.warm import discover_compositions

    comps = discover_compositions()
    assert [c.terminal for c in comps] == ["amplifier", "open_circuit"]
    before = {n for n in sys.modules if n.startswith("_mfc_shm_kernel_")}
    comps[0].model().uncached_kernels(comps[0].entries)
    warmed = {n for n in sys.modules if n.startswith("_mfc_shm_kernel_")} - before
    scales = {"z1": 9e-4, "zd1": 0.016, "delta1": 9e-4, "ddelta1": 0.016, "z2": 2e-3, "zd2": 0.04, "delta2": 1e-3,
              "ddelta2": 0.028, "z3": 3.4e-3, "zd3": 0.11, "delta3": 1.5e-3, "ddelta3": 0.088, "vc": 300.0,
              "va": 300.0, "ic": 2e-3, "one": 1.0, "t": 2.0}  # a 2 s MBIT.b record's
    cls = generated_effect(dictionary_source(build_dictionary(scales, driven=True)), "dictionary_driven")
    PlantModel("table2", effects=[cls], terminal="amplifier").uncached_kernels(comps[0].entries)
    assert len(warmed) == 1 and {n for n in sys.modules if n.startswith("_mfc_shm_kernel_")} - before == warmed


def test_large_kernels_compile_side_by_side_only_as_memory_allows():
    # two dictionary kernels (12.6 GB each while LLVM optimises them) side by side were killed for memory on 24 GiB
    from plant.warm import available_memory_bytes, jobs_for_memory
    from workbench.warm import DICTIONARY_PEAK_BYTES, discover_compositions

    gib = 2**30
    assert jobs_for_memory(2, 14 * gib, 24 * gib) == 1 and jobs_for_memory(4, 14 * gib, 60 * gib) == 4
    assert jobs_for_memory(2, 14 * gib, 0) == 1  # unreadable memory: one at a time, never none
    assert jobs_for_memory(3, 0, 8 * gib) == 3
    assert all(c.peak_bytes == DICTIONARY_PEAK_BYTES for c in discover_compositions())
    assert not any(c.peak_bytes for c in shipped_compositions())
    assert available_memory_bytes() > 0
