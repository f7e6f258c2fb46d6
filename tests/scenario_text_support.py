"""Scenario-file texts for tests (docs/scenarios.md): ``[[phase]]`` tables, ``[[life.law]]`` tables and a small
``[life]`` scenario, written one way for every test that needs a short scenario or life on disk."""

from __future__ import annotations


def phases(*rows: tuple[str, str] | tuple[str, str, str] | tuple[str, str, str, str], sep: str = "") -> str:
    """``[[phase]]`` tables, one per row ``(kind, duration in s as written[, name[, more lines]])``, joined by
    ``sep`` (``"\\n"``: a blank line between tables)."""
    tables = []
    for kind, duration_s, *rest in rows:
        name = f'name = "{rest[0]}"\n' if rest and rest[0] else ""
        more = rest[1] if len(rest) > 1 else ""
        tables.append(f'[[phase]]\n{name}kind = "{kind}"\nduration = {{ value = {duration_s}, unit = "s" }}\n{more}')
    return sep.join(tables)


def linear_law(parameter: str = "alpha_h", rate_per_h: str = "2e-4") -> str:
    """A ``[[life.law]]`` table: ``parameter`` drifting linearly at ``rate_per_h`` (1/h, as written)."""
    return (f'[[life.law]]\nparameter = "{parameter}"\nkind = "linear"\n'
            f'rate = {{ value = {rate_per_h}, unit = "1/h" }}\n')


#: one maintenance visit of a life: half a second parked, 29 s of maintenance (MBIT.a, MBIT.b, verdict)
VISIT_PHASES = (("ground", "0.5"), ("maintenance", "29"))


def life_scenario(name: str, visits: int, interval_h: int, *, seed: int = 3, rig: str = "", more_life: str = "",
                  laws: tuple[str, ...] = (linear_law(),),
                  visit: tuple[tuple[str, str], ...] = VISIT_PHASES, sep: str = "") -> str:
    """A ``[life]`` scenario: ``visits`` visits ``interval_h`` h apart, each the phases of ``visit``; ``rig`` and
    ``more_life`` are extra lines of ``[rig]`` (the table left out when empty) and ``[life]``; tables joined by
    ``sep``."""
    tables = [f'[scenario]\nname = "{name}"\nseed = {seed}\n', f"[rig]\n{rig}" if rig else "",
              f'[life]\nvisits = {{ value = {visits}, unit = "1" }}\n'
              f'visit_interval = {{ value = {interval_h}, unit = "h" }}\n{more_life}', *laws, phases(*visit, sep=sep)]
    return sep.join(t for t in tables if t)


def gust(at_s: str, peak_m_s2: str, duration_s: str) -> str:
    """An ``[[event]]`` table: a gust of ``peak_m_s2`` (m/s², as written) at ``at_s`` for ``duration_s`` (s)."""
    return (f'[[event]]\nkind = "gust"\nat = {{ value = {at_s}, unit = "s" }}\n'
            f'peak = {{ value = {peak_m_s2}, unit = "m/s^2" }}\nduration = {{ value = {duration_s}, unit = "s" }}\n')
