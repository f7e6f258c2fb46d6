"""``shm effects list|show``: the physical effects the plant can be composed of, and what each one models.

    shm effects list [--all] [--json]
    shm effects show NAME [--json]

``list`` prints the library effects (those ``shm diagnose`` tries and ``--effect`` adds; ``--all`` adds the core
effects of the nominal model and the terminals) with their parameters. ``show`` prints one effect: what it models
(``description``, ``origin``), what its absence leaves in residuals (``signature``), and every parameter with its SI
unit, default, bounds, neutral value (the value at which the effect leaves the model unchanged) and the range a fit
searches (declared by the effect, or derived from the bounds), plus its states, outputs and bus signals. NAME is what
``--effect`` accepts: a registered name, ``package.module:ClassName``, ``path/to/effect.py[:ClassName]``, with an
optional ``as PREFIX``. Catalogue: docs/effects.md.
"""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING, Any

from shm_cli.command_args import add_command_group
from shm_cli.common import dump_json

if TYPE_CHECKING:
    from plant import PhysicalEffect


def register(sub: argparse._SubParsersAction) -> None:
    esub = add_command_group(
        sub, "effects", "list the physical effects, or show one: parameters, units, neutral values, fit ranges, what "
        "it models", "The physical effects the plant is composed of (docs/effects.md).")
    pl = esub.add_parser("list", help="the library effects (--all: also the core effects and terminals)")
    pl.add_argument("--all", action="store_true", help="also the core effects of the nominal model and the terminals")
    pl.add_argument("--json", action="store_true", help="print the list as one JSON document")
    pl.set_defaults(func=cmd_list)
    ps = esub.add_parser("show", help="one effect: what it models, its parameters (unit, default, bounds, neutral "
                                      "value, fit range), states, outputs and signals")
    ps.add_argument("name", metavar="NAME|pkg.mod:Class|FILE.py[:Class]",
                    help="a registered effect name, a dotted path or an effect file (what --effect accepts)")
    ps.add_argument("--json", action="store_true", help="print the description as one JSON document")
    ps.set_defaults(func=cmd_show)


# ------------------------------------------------------------------------------------------------ describing
def _number(v: float | None) -> float | str | None:
    """A JSON-safe number (infinite bounds as the strings "inf" / "-inf")."""
    if v is None or math.isfinite(v):
        return v
    return "inf" if v > 0 else "-inf"


def _parameter(cls: type[PhysicalEffect], par: Any, fitted: set[str]) -> dict[str, Any]:
    """One parameter of ``cls``: unit, default, bounds, neutral value and fit range (SI)."""
    from workbench.fit import effect_free_parameters

    if par.core_index is not None:
        return {"name": par.name, "kind": "core (Table 2, from the parameter set)", "unit": par.unit,
                "default": par.default, "lower": _number(par.lower), "upper": _number(par.upper),
                "neutral": None, "fit": None, "fitted_by_default": False, "description": par.description}
    neutral = par.neutral
    freed = effect_free_parameters(cls, [par.name])[0]
    scale = "log" if freed.fit_range.log else ("symlog" if freed.fit_range.linthresh else "linear")
    fit = {"lower": freed.lower, "upper": freed.upper, "scale": scale,
           "linthresh": freed.fit_range.linthresh,
           "source": "declared by the effect" if par.fit is not None else
           "derived from the bounds"}
    return {"name": par.name, "kind": "own", "unit": par.unit, "default": par.default, "lower": _number(par.lower),
            "upper": _number(par.upper), "neutral": None if neutral is None else float(neutral), "fit": fit,
            "fitted_by_default": par.name in fitted, "description": par.description}


def describe(cls: type[PhysicalEffect], spec: str | None = None) -> dict[str, Any]:
    """Everything ``shm effects show`` says about an effect class, JSON-able (SI units); ``spec`` is how the user
    named it (what ``--effect`` takes; default: its registered name)."""
    from plant.effect import effect_source_file, library_effects
    from workbench.fit import effect_free_parameters

    own = cls.own_parameters()
    fitted = {p.name for p in effect_free_parameters(cls)} if own and cls.role == "effect" else set()
    return {
        "name": cls.name, "spec": spec or cls.name, "role": cls.role, "class": f"{cls.__module__}:{cls.__qualname__}",
        "file": effect_source_file(cls), "in_library": cls.name in library_effects(),
        "description": cls.description, "models": " ".join((cls.origin or "").split()),
        "signature": " ".join((cls.signature or "").split()),
        "parameters": [_parameter(cls, par, fitted) for par in cls.parameters],
        "states": [{"name": s.name, "unit": s.unit, "scale": s.scale, "initial": s.initial} for s in cls.states],
        "outputs": [{"name": o.name, "unit": o.unit} for o in cls.outputs],
        "signals": [{"name": s.name, "unit": s.unit, "description": s.description} for s in cls.signals],
        "reads": list(cls.reads),
    }


# ------------------------------------------------------------------------------------------------ commands
def cmd_list(args: argparse.Namespace) -> int:
    from plant.effect import library_effects, registered_effects

    registry = registered_effects()
    names = list(library_effects())
    if args.all:
        order = {"core": 0, "terminal": 1, "effect": 2}
        names += sorted((n for n in registry if n not in names), key=lambda n: (order[registry[n].role], n))
    rows = [{"name": n, "role": registry[n].role, "description": registry[n].description,
             "parameters": [f"{p.name} [{p.unit}]" for p in registry[n].own_parameters()]} for n in names]
    if args.json:
        print(dump_json({"effects": rows}))
        return 0
    print(f"{len(rows)} effects" + ("" if args.all else " in the library (--all: also the core effects and "
                                                        "terminals)") + "; `shm effects show NAME` for one:")
    width = max(len(r["name"]) for r in rows)
    for r in rows:
        role = "" if r["role"] == "effect" else f"[{r['role']}] "
        print(f"  {r['name']:<{width}}  {role}{r['description']}")
        if r["parameters"]:
            print(f"  {'':<{width}}    parameters: {', '.join(r['parameters'])}")
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    from plant import resolve_effect

    d = describe(resolve_effect(args.name), args.name)
    if args.json:
        print(dump_json(d))
        return 0
    for line in _show_lines(d):
        print(line)
    return 0


def _fmt(v: Any) -> str:
    return f"{v:g}" if isinstance(v, float | int) and not isinstance(v, bool) else str(v)


def _show_lines(d: dict[str, Any]) -> list[str]:
    lines = [f"{d['name']} ({d['role']}{', library' if d['in_library'] else ''}): {d['description']}",
             f"  class   {d['class']}" + (f" (file {d['file']})" if d["file"] else "")]
    if d["models"]:
        lines.append(f"  models  {d['models']}")
    if d["signature"]:
        lines.append(f"  absent, it leaves in residuals: {d['signature']}")
    lines.append(f"  parameters ({len(d['parameters'])}; SI units):" if d["parameters"] else "  no parameters")
    for p in d["parameters"]:
        lines.append(f"    {p['name']} [{p['unit']}] — {p['description']}" if p["description"] else
                     f"    {p['name']} [{p['unit']}]")
        if p["kind"] != "own":
            lines.append(f"      {p['kind']}; bounds [{_fmt(p['lower'])}, {_fmt(p['upper'])}]")
            continue
        neutral = "none declared" if p["neutral"] is None else _fmt(p["neutral"])
        lines.append(f"      default {_fmt(p['default'])}, bounds [{_fmt(p['lower'])}, {_fmt(p['upper'])}], "
                     f"neutral {neutral}")
        f = p["fit"]
        scale = f["scale"] + (f" within ±{f['linthresh']:g}" if f["linthresh"] else "")
        lines.append(f"      fit range [{_fmt(f['lower'])}, {_fmt(f['upper'])}] {scale}, {f['source']}"
                     + ("; fitted by default" if p["fitted_by_default"] else ""))
    for key, title in (("states", "states"), ("outputs", "outputs"), ("signals", "bus signals")):
        if d[key]:
            lines.append(f"  {title}: " + ", ".join(f"{x['name']} [{x['unit']}]" for x in d[key]))
    if d["reads"]:
        lines.append(f"  reads signals: {', '.join(d['reads'])}")
    own = [p for p in d["parameters"] if p["kind"] == "own"]
    if d["role"] == "effect" and own:
        example = own[0]
        spec = f"'{d['spec']}'" if " " in d["spec"] else d["spec"]
        lines.append(f"  try: shm synth --test mbit-a --effect {spec} --set {example['name']}=VALUE --out x.csv"
                     + (f" (at {_fmt(example['neutral'])}, its neutral value, it leaves the plant nominal)"
                        if example["neutral"] is not None else ""))
    return lines
