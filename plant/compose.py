"""Compose effects into compiled kernels: generate one module per composition and let numba cache it.

For a composition (an ordered tuple of effect classes laid out by :mod:`plant.composition`) we generate Python
source that imports each effect, compiles its hooks, binds each effect's slot tables (``_slots0_X``, ...: named
tuples of integer constants) or offsets, defines ``rhs``/``out`` calling the hooks in phase order, and pastes
the batch integrator (:data:`plant.integrate.INTEGRATOR_SOURCE`). When every effect is importable by
module path, the source is written to a cache directory and imported as a file, so numba's on-disk cache
applies (``cache=True``): later processes load machine code instead of compiling for seconds. Effects
that cannot be imported by path (defined in ``__main__`` or inside a function) are compiled in memory.

The cache key covers the generated source (hence the slots and constants), numba's version and the source of
every effect's module *and of the modules it imports* from outside the standard library and site-packages
(``plant.layout``, helper modules, ...), transitively: numba freezes their constants and inlines their functions
into the cached machine code, so an edit there must recompile.
"""

from __future__ import annotations

import ast
import functools
import hashlib
import importlib
import importlib.util
import inspect
import os
import sys
import sysconfig
import threading
from pathlib import Path
from types import ModuleType

import numba
from numba import types

from plant import integrate_steps, kernel_cache
from plant import layout as L
from plant.composition import Composition, build_composition
from plant.effect import EffectError, PhysicalEffect, effect_source_file, hook_function, importable_by_path
from plant.integrate import INTEGRATOR_SOURCE, LANE_INTEGRATOR_SOURCE, LANES, TABLEAU_NAMES
from plant.lanes import OUTPUT_ROLES, PHASE_ROLES, LaneFormUnsupported, lane_hook_source

HOOK_SIG = types.void(types.float64, types.float64[::1], types.float64[::1], types.float64[::1],
                      types.float64[::1], types.int64, types.int64)
OUT_SIG = types.void(types.float64, types.float64[::1], types.float64[::1], types.float64[::1],
                     types.float64[::1], types.int64, types.int64, types.int64)
PHASES = ("pre", "rates", "post")
_GENERATOR_VERSION = "9"

#: the compiled entry points of a kernel module: member by member (``run_chunk``; ``run_chunk_stats`` counts steps),
#: the lane integrator (``run_lanes``, batches of 16 or more) and the Python-callable right-hand side and outputs
KERNEL_ENTRIES = ("run_chunk", "run_chunk_stats", "run_lanes", "rhs", "out")

_LOADED: dict[str, ModuleType] = {}
_LOCK = threading.Lock()


def kernel_dir() -> Path:
    """Where generated kernel modules live: ``$MFC_SHM_KERNEL_DIR``, else beside numba's cache."""
    env = os.environ.get("MFC_SHM_KERNEL_DIR")
    if env:
        return Path(env)
    base = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(os.path.expanduser("~"), ".cache", "mfc-shm")
    return Path(base) / "kernels"


_MODULE_FACTS: dict[tuple[str, int, int], tuple[str, tuple[str, ...]]] = {}


def _outside_project(module: ModuleType) -> bool:
    """True for built-in, standard-library and installed (site-packages) modules."""
    path = getattr(module, "__file__", None)
    if not path:
        return True
    return _path_outside_project(path)


@functools.cache
def _library_roots() -> tuple[str, ...]:
    """The standard library's and site-packages' folders, resolved (fixed for the process)."""
    paths = sysconfig.get_paths()
    roots = {paths.get(k) for k in ("stdlib", "platstdlib", "purelib", "platlib")} - {None}
    return tuple(os.path.realpath(str(r)) + os.sep for r in roots)


@functools.lru_cache(maxsize=4096)
def _path_outside_project(path: str) -> bool:
    """Whether a module file lies in the standard library or site-packages (memoised: a composition's
    fingerprint asks this of every module its effects import, ~0.3 ms a call — 11 s of a 76 s diagnose)."""
    return os.path.realpath(path).startswith(_library_roots())


def _module_facts(module: ModuleType) -> tuple[str, tuple[str, ...]]:
    """(digest of the module's source, names of the modules it takes names from); memoised per file version."""
    path = getattr(module, "__file__", None) or ""
    try:
        mtime = os.stat(path).st_mtime_ns if path else 0
    except OSError:
        mtime = 0
    key = (module.__name__, id(module), mtime)
    facts = _MODULE_FACTS.get(key)
    if facts is None:
        facts = (_module_digest(module), tuple(_imported_modules(module)))
        _MODULE_FACTS[key] = facts
    return facts


def _module_digest(module: ModuleType) -> str:
    # a module loaded from a file (plant.effect.load_effect_file) carries the digest of the file's bytes
    digest = getattr(module, "__mfc_shm_digest__", None)
    if digest:
        return str(digest)[:16]
    try:
        return hashlib.sha256(inspect.getsource(module).encode()).hexdigest()[:16]
    except (OSError, TypeError):
        return "nosource"


def _imported_modules(module: ModuleType) -> list[str]:
    """The modules ``module`` takes names from: ``import m`` gives m; ``from m import f`` gives the module that
    *defines* f when f is a function or class (so ``from plant import PhysicalEffect`` follows plant.effect, not
    the whole package), m itself for constants, m.f when f is a module."""
    try:
        tree = ast.parse(inspect.getsource(module))
    except (OSError, TypeError, SyntaxError):
        return []
    package = module.__name__ if hasattr(module, "__path__") else module.__name__.rpartition(".")[0]
    out: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                parent = ".".join(parts[: len(parts) - node.level + 1]) if node.level <= len(parts) else ""
                base = f"{parent}.{base}" if base and parent else (parent or base)
            source = sys.modules.get(base)
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                obj = getattr(source, alias.name, None) if source is not None and alias.name != "*" else None
                if sub in sys.modules:
                    out.append(sub)
                elif obj is not None and (callable(obj) or isinstance(obj, type)) and \
                        getattr(obj, "__module__", None) in sys.modules:
                    out.append(obj.__module__)
                else:
                    out.append(base)
    return out


def _module_closure(name: str) -> list[ModuleType]:
    """``name``'s module and, transitively, the project modules it takes names from (not stdlib or
    site-packages)."""
    seen: dict[str, ModuleType] = {}
    todo = [name]
    while todo:
        mod_name = todo.pop()
        if mod_name in seen:
            continue
        module = sys.modules.get(mod_name)
        if module is None or (seen and _outside_project(module)):
            continue
        seen[mod_name] = module
        todo += [m for m in _module_facts(module)[1] if m in sys.modules and m not in seen]
    return [seen[k] for k in sorted(seen)]


def _source_fingerprint(cls: type) -> str:
    """Digest of the source of ``cls``'s module, of the modules its hooks come from, and of every project module
    they import (transitively): what numba compiles into the cached kernel."""
    names = {cls.__module__}
    for hook in (*PHASES, "output"):
        fn = hook_function(cls, hook)
        if fn is not None and getattr(fn, "__module__", None):
            names.add(fn.__module__)
    modules: dict[str, ModuleType] = {}
    for n in sorted(names):
        for m in _module_closure(n):
            modules.setdefault(m.__name__, m)
    if not modules:
        return "nosource"
    return hashlib.sha256("|".join(f"{k}:{_module_facts(m)[0]}" for k, m in sorted(modules.items())).encode()
                          ).hexdigest()[:16]


def _hook_call(comp: Composition, k: int, hook: str) -> str:
    slot = comp.slots[k]
    if slot.styles[hook] == "offsets":
        args = [slot.state_offset, slot.param_offset] + ([slot.output_offset] if hook == "output" else [])
        return ", ".join(str(a) for a in args)
    kinds = ("X", "P", "B", "Y") if hook == "output" else ("X", "P", "B")
    return ", ".join(f"_slots{k}_{kind}" for kind in kinds)


#: the core outputs: (output slot, source array, source slot) for each section i = 0..2, then single channels
_SECTION_OUTPUTS = ((L.Y_Z, "bus", f"{L.B_Z}"), (L.Y_DELTA, "x", f"{L.X_DELTA}"), (L.Y_Q, "x", f"{L.X_Q}"),
                    (L.Y_QH, "bus", f"{L.B_QH}"), (L.Y_VPATCH, "bus", f"{L.B_VC}"))
_SINGLE_OUTPUTS = ((L.Y_VSTORED, "bus", f"{L.B_VA}"), (L.Y_Z3_MEAS, "bus", f"{L.B_Z} + 2"))


def _core_output_lines(lanes: bool) -> list[str]:
    """Generated lines filling the core outputs from the states and the bus: ``out`` (``y[...] = bus[...]``) or
    ``out_lanes`` (the same rows of the work array, every lane)."""
    if not lanes:
        return ["    for i in range(3):",
                *(f"        y[{ys} + i] = {arr}[{src} + i]" for ys, arr, src in _SECTION_OUTPUTS),
                *(f"    y[{ys}] = {arr}[{src}]" for ys, arr, src in _SINGLE_OUTPUTS)]
    return ["    for i in range(3):",
            "        for l in range(LANES):",
            *(f"            W[(ROW_y + {ys} + i) * LANES + l] = W[(ROW_{arr} + {src} + i) * LANES + l]"
              for ys, arr, src in _SECTION_OUTPUTS),
            "    for l in range(LANES):",
            *(f"        W[(ROW_y + {ys}) * LANES + l] = W[(ROW_{arr} + {src}) * LANES + l]"
              for ys, arr, src in _SINGLE_OUTPUTS)]


def generate_source(classes: tuple[type[PhysicalEffect], ...], s_off: tuple[int, ...], p_off: tuple[int, ...],
                    y_off: tuple[int, ...], n_states: int, cacheable: bool,
                    integrator_source: str = INTEGRATOR_SOURCE, composition: Composition | None = None) -> str:
    """The Python source of the composed kernels (see the module docstring); ``integrator_source`` replaces
    the batch integrator (the benchmark times the previous one against the current one). ``composition`` is
    the layout (:func:`plant.composition.build_composition` of ``classes`` when not given; its offsets are
    those of ``s_off``/``p_off``/``y_off``)."""
    comp = composition if composition is not None else build_composition(classes)
    if comp.offsets != (tuple(s_off), tuple(p_off), tuple(y_off)):
        raise EffectError(f"offsets {s_off, p_off, y_off} do not match the layout of {[c.name for c in classes]}")
    cache = "True" if cacheable else "False"
    lines = [
        "# Generated by plant.compose. Do not edit: regenerated from the effects it names.",
        f"# effects: {', '.join(c.name for c in classes)}",
        "from __future__ import annotations  # the integrators' annotations (plant.integrate_*) stay text",
        "",
        "import importlib",
        "import numba",
        "import numpy as np",
        "from plant.composition import slot_table",
        # the integrator's constants as literals: a changed constant changes the source, hence the cache key
        # (numba's on-disk cache keys on this file, not on plant.integrate_steps)
        *(f"{name} = {getattr(integrate_steps, name)!r}" for name in TABLEAU_NAMES),
        f"CACHE = {cache}",
        f"N_STATES = {n_states}",
        f"N_BUS = {L.N_BUS}",
        "",
    ]
    for k, cls in enumerate(classes):
        if cacheable:  # an instance (prefix) runs the hooks of the class it is an instance of
            src = cls.instance_of or cls
            lines.append(f"_EFF{k} = importlib.import_module({src.__module__!r})")
            for part in src.__qualname__.split("."):
                lines.append(f"_EFF{k} = _EFF{k}.{part}")
        for hook in (*PHASES, "output"):
            if getattr(cls, hook) is not None:
                lines.append(f"e{k}_{hook} = numba.njit(cache=CACHE, nogil=True, error_model='numpy', "
                             f"inline='always')(_EFF{k}.{hook})")
        tables = comp.slots[k].tables
        if tables is not None:
            for kind, names in tables.items():
                lines.append(f"_slots{k}_{kind} = slot_table({kind!r}, {tuple(names)!r}, "
                             f"{tuple(names.values())!r})")
    lines += [
        "",
        "",
        "@numba.njit(cache=CACHE, nogil=True, error_model='numpy')",
        "def rhs(t, x, p, u, bus, dx):",
        "    for i in range(bus.shape[0]):",
        "        bus[i] = 0.0",
        "    for i in range(dx.shape[0]):",
        "        dx[i] = 0.0",
        f"    bus[{L.B_T}] = t",
        f"    bus[{L.B_U_V1}] = u[{L.U_V_CH1}]",
        f"    bus[{L.B_U_V2}] = u[{L.U_V_CH2}]",
        f"    bus[{L.B_Z0DD}] = u[{L.U_Z0DD}]",
    ]
    for phase in PHASES:
        for k, cls in enumerate(classes):
            if getattr(cls, phase) is not None:
                lines.append(f"    e{k}_{phase}(t, x, p, bus, dx, {_hook_call(comp, k, phase)})")
    lines += [
        "",
        "",
        "@numba.njit(cache=CACHE, nogil=True, error_model='numpy')",
        "def out(t, x, p, u, bus, dx, y):",
        "    rhs(t, x, p, u, bus, dx)",
        *_core_output_lines(lanes=False),
    ]
    for k, cls in enumerate(classes):
        if cls.output is not None:
            lines.append(f"    e{k}_output(t, x, p, bus, y, {_hook_call(comp, k, 'output')})")
    lines += ["", "", integrator_source]
    lane_lines = _lane_section(classes, comp, n_states) if cacheable and integrator_source == INTEGRATOR_SOURCE \
        else None
    lines += lane_lines if lane_lines is not None else ["", "HAS_LANES = False", "LANES = 1"]
    return "\n".join(lines) + "\n"


def _lane_section(classes: tuple[type[PhysicalEffect], ...], comp: Composition, n_states: int) -> list[str] | None:
    """The lane-form kernels (:mod:`plant.lanes`): work-array layout, lane hooks, ``rhs_lanes``, ``out_lanes`` and
    the lane integrator; None when a hook cannot be rewritten, or when an effect comes from an effect file (the
    composition then integrates member by member only). An effect file is usually a candidate tried once (a
    discovered term, ``shm fit --add file.py``): its lane kernels would take ~8 s to compile, more than they save on
    one fit (the discovery challenge's 80 refits took 840 s with them, 371 s without)."""
    if any(effect_source_file(c.instance_of or c) for c in classes):
        return None
    n_params = L.N_CORE_PARAMS + len(comp.parameters)
    n_outputs = L.N_CORE_OUTPUTS + len(comp.outputs)
    rows = {"x": n_states, "p": n_params, "bus": L.N_BUS, "dx": n_states, "y": n_outputs, "u": L.N_INPUTS,
            "atol": n_states, "xc": n_states, **{f"k{i}": n_states for i in range(1, 8)}, "xn": n_states,
            "err": 1, "tot": 1, "alive": 1}
    lines = ["", "", "# --- lane form (plant.lanes): LANES members per work array W, row r lane l at W[r * LANES + l]",
             "HAS_LANES = True", f"LANES = {LANES}", f"N_PARAMS = {n_params}", f"N_OUTPUTS = {n_outputs}"]
    offset = 0
    for name, size in rows.items():
        lines.append(f"ROW_{name} = {offset}")
        offset += size
    lines.append(f"W_ROWS = {offset}")
    calls: dict[str, list[str]] = {hook: [] for hook in (*PHASES, "output")}
    for k, cls in enumerate(classes):
        for hook in (*PHASES, "output"):
            fn = hook_function(cls, hook)
            if fn is None:
                continue
            try:
                src, needed = lane_hook_source(fn, f"l{k}_{hook}", f"{k}_{hook}",
                                               OUTPUT_ROLES if hook == "output" else PHASE_ROLES)
            except LaneFormUnsupported:
                return None
            if needed:
                lines.append(f"_HM{k}_{hook} = importlib.import_module({fn.__module__!r})")
                lines += [f"{bound} = _HM{k}_{hook}.{name}" for bound, name in needed.items()]
            lines += ["@numba.njit(cache=CACHE, nogil=True, error_model='numpy', inline='always')", src]
            calls[hook].append(f"    l{k}_{hook}(t, W, {_hook_call(comp, k, hook)})")
    lines += [
        "",
        "",
        "@numba.njit(cache=CACHE, nogil=True, error_model='numpy')",
        "def rhs_lanes(t, W):",
        "    for i in range(ROW_bus * LANES, (ROW_dx + N_STATES) * LANES):",
        "        W[i] = 0.0",
        "    for l in range(LANES):",
        f"        W[(ROW_bus + {L.B_T}) * LANES + l] = t",
        f"        W[(ROW_bus + {L.B_U_V1}) * LANES + l] = W[(ROW_u + {L.U_V_CH1}) * LANES + l]",
        f"        W[(ROW_bus + {L.B_U_V2}) * LANES + l] = W[(ROW_u + {L.U_V_CH2}) * LANES + l]",
        f"        W[(ROW_bus + {L.B_Z0DD}) * LANES + l] = W[(ROW_u + {L.U_Z0DD}) * LANES + l]",
    ]
    for phase in PHASES:
        lines += calls[phase]
    lines += [
        "",
        "",
        "@numba.njit(cache=CACHE, nogil=True, error_model='numpy')",
        "def out_lanes(t, W):",
        "    rhs_lanes(t, W)",
        *_core_output_lines(lanes=True),
        *calls["output"],
        "",
        "",
        LANE_INTEGRATOR_SOURCE,
    ]
    return lines


def _diagnose_hooks(classes: tuple[type[PhysicalEffect], ...], comp: Composition) -> None:
    """After a failed build: compile each hook alone and raise an error naming the culprit."""
    for k, cls in enumerate(classes):
        for hook in (*PHASES, "output"):
            fn = hook_function(cls, hook)
            if fn is None:
                continue
            if comp.slots[k].styles[hook] == "offsets":
                sig = OUT_SIG if hook == "output" else HOOK_SIG
            else:
                arr = types.float64[::1]
                tables = tuple(numba.typeof(a) for a in comp.hook_args(k, hook))
                sig = types.void(types.float64, arr, arr, arr, arr, *tables)
            try:
                numba.njit(sig, cache=False)(fn)
            except Exception as exc:
                first = str(exc).strip().splitlines()
                raise EffectError(
                    f"effect '{cls.name}' ({cls.__module__}.{cls.__qualname__}): hook '{hook}' does not compile "
                    f"with numba (hooks must be numba-compilable: scalars, numpy arrays, math; slot tables by "
                    f"declared names): {type(exc).__name__}: {first[0] if first else ''}") from exc


def compose(classes: tuple[type[PhysicalEffect], ...], s_off: tuple[int, ...], p_off: tuple[int, ...],
            y_off: tuple[int, ...], n_states: int, integrator_source: str = INTEGRATOR_SOURCE,
            composition: Composition | None = None) -> ModuleType:
    """The compiled kernel module of a composition (``rhs``, ``out``, ``run_chunk``), built or loaded."""
    comp = composition if composition is not None else build_composition(classes)
    cacheable, source, key = _source_and_key(classes, s_off, p_off, y_off, n_states, integrator_source, comp)
    with _LOCK:
        if key in _LOADED:
            return _LOADED[key]
        name = f"_mfc_shm_kernel_{key}"
        try:
            if cacheable:
                module = _load_file_module(name, source)
            else:
                module = ModuleType(name)
                for k, cls in enumerate(classes):
                    setattr(module, f"_EFF{k}", cls)
                exec(compile(source, f"<composed plant {name}>", "exec"), module.__dict__)
            # for compile announcements (attributes of the module object, not of its source: the cache key)
            module.__dict__.update(EFFECT_CLASSES=tuple(classes), ANNOUNCED=set())
            announce_if_cold(module, "run_chunk")
            # force compilation now so that errors surface here, with names
            _warm_up(module, n_states)
        except EffectError:
            raise
        except Exception as exc:
            _diagnose_hooks(classes, comp)
            raise EffectError(f"composing effects {[c.name for c in classes]} failed: "
                              f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}") from exc
        _LOADED[key] = module
        return module


def _source_and_key(classes: tuple[type[PhysicalEffect], ...], s_off: tuple[int, ...], p_off: tuple[int, ...],
                    y_off: tuple[int, ...], n_states: int, integrator_source: str, comp: Composition
                    ) -> tuple[bool, str, str]:
    """(whether the composition can be cached on disk, its generated source, its cache key)."""
    cacheable = all(importable_by_path(c.instance_of or c) for c in classes)
    source = generate_source(classes, s_off, p_off, y_off, n_states, cacheable, integrator_source, comp)
    fingerprint = "|".join([_GENERATOR_VERSION, numba.__version__, source,
                            *(_source_fingerprint(c) for c in classes)])
    return cacheable, source, hashlib.sha256(fingerprint.encode()).hexdigest()[:20]


def uncached_entries(classes: tuple[type[PhysicalEffect], ...], s_off: tuple[int, ...], p_off: tuple[int, ...],
                     y_off: tuple[int, ...], n_states: int, entries: tuple[str, ...],
                     composition: Composition | None = None) -> list[str]:
    """Which of a composition's kernel ``entries`` (``run_chunk``, ``run_lanes``, ...) a first call would compile:
    neither compiled in this process nor in numba's on-disk cache (:func:`plant.kernel_cache.is_cached`). Reads
    the cache's index only — compiles and loads no machine code; a composition compiled in memory (not cacheable)
    has them all to compile. An entry the module does not have (no lane form) is left out."""
    comp = composition if composition is not None else build_composition(classes)
    cacheable, source, key = _source_and_key(classes, s_off, p_off, y_off, n_states, INTEGRATOR_SOURCE, comp)
    with _LOCK:
        module = _LOADED.get(key)
        if module is None:
            if not cacheable:
                return list(entries)
            module = _load_file_module(f"_mfc_shm_kernel_{key}", source)
    return [e for e in entries if hasattr(module, e) and not kernel_cache.is_cached(getattr(module, e))]


def announce_if_cold(module: ModuleType, entry: str) -> None:
    """Announce on stderr (:func:`plant.kernel_cache.announce_compile`) that calling ``entry`` of a composed
    kernel module will compile it — not in numba's on-disk cache, nor compiled in this process; once per module
    and entry. A warm start says nothing."""
    seen: set[str] = module.__dict__.setdefault("ANNOUNCED", set())
    if entry in seen:
        return
    seen.add(entry)
    dispatcher = getattr(module, entry, None)
    if dispatcher is not None and not kernel_cache.is_cached(dispatcher):
        kernel_cache.announce_compile(module.__dict__.get("EFFECT_CLASSES", ()), entry)


def _load_file_module(name: str, source: str) -> ModuleType:
    directory = kernel_dir()
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{name}.py"
    if not path.exists() or path.read_text() != source:
        tmp = directory / f".{name}.{os.getpid()}.{threading.get_ident()}.tmp"
        tmp.write_text(source)
        os.replace(tmp, path)
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(name, None)
        raise
    return module


def _warm_up(module: ModuleType, n_states: int) -> None:
    import numpy as np

    x = np.zeros((1, n_states))
    p = np.zeros((1, L.N_CORE_PARAMS + 64))
    p[0, :L.N_CORE_PARAMS] = 1.0
    u = np.zeros((1, 2, L.N_INPUTS))
    t_out = np.array([0.0])
    y = np.zeros((1, 1, L.N_CORE_OUTPUTS + 64))
    module.run_chunk(0, 0, x, p, u, 0.0, 1.0, t_out, 1e-6, np.ones(n_states), 1e-3, 1e-14, 10,
                     y, np.zeros((1, 1, 1)), np.zeros((1, 1, 1)), False, False,
                     np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.int64))
