"""The prognosis challenge's lives: degradation laws, visit schedules, noise — and what kind of life each is.

Groups (``ChallengeLife.group``): ``core`` (the monitor's parameters degrade along the candidate laws: linear, power,
exponential), ``effect`` (an added effect degrades — the patches' leakage conductance G_leak rising linearly, the
laminate itself nominal), ``few-visits`` (visits every 400 h: four or five visits before the first FAULT),
``out-of-family`` (a law none of the candidate trend laws is: a logistic, a two-stage wear), ``other-section``
(a section-2 stiffness loss beside an α_h drift: the default set's k3 is not where it happens), ``stable`` and
``sudden``. :func:`challenge_lives` builds them at a chosen size: ``"smoke"`` (one life per kind that ``make test``
affords), ``"full"`` (the bench), or the full set cut to ``per_group`` lives of each group.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from board_config.scenario import LifeLaw
from studies.health.laws import deviations_at, law_value


@dataclass(frozen=True)
class LogisticLaw:
    """A truth law outside the candidate trend laws: d(h) = A / (1 + exp(−(h − h_mid)/w)) − (its value at 0)."""

    parameter: str
    amplitude: float
    midpoint: float  # h
    width: float  # h

    def value(self, hours: float) -> float:
        def s(h: float) -> float:
            return self.amplitude / (1.0 + math.exp(-(h - self.midpoint) / self.width))

        return s(hours) - s(0.0)


@dataclass(frozen=True)
class ChallengeLife:
    name: str
    laws: tuple[LifeLaw | LogisticLaw, ...]
    visits: int = 16
    interval: float = 100.0  # h
    noise_m: float = 2e-6  # laser noise, 1 sigma
    kind: str = "trend"  # trend | stable | sudden
    step_hours: float | None = None  # sudden damage: when (h)
    step_parameter: str | None = None
    seed: int = 0
    #: effects added to the truth plant; laws on their parameters give the parameter's value itself (SI)
    effects: tuple[str, ...] = ()
    group: str = "core"

    def hours(self) -> np.ndarray:
        return self.interval * np.arange(self.visits)

    def truth_at(self, hours: float) -> tuple[dict[str, float], dict[str, float]]:
        """(relative deviations of core parameters, SI values of the added effects' parameters) at ``hours``."""
        from plant.effect import resolve_effect

        eff_params = {p.name for e in self.effects for p in resolve_effect(e).parameters}
        core_laws = [law for law in self.laws if isinstance(law, LifeLaw) and law.parameter not in eff_params]
        devs = deviations_at(core_laws, hours)
        eff: dict[str, float] = {}
        for law in self.laws:
            if isinstance(law, LogisticLaw):
                devs[law.parameter] = devs.get(law.parameter, 0.0) + law.value(hours)
            elif law.parameter in eff_params:
                eff[law.parameter] = eff.get(law.parameter, 0.0) + law_value(law, hours)
        return devs, eff


def _lin(p: str, rate: float) -> LifeLaw:
    return LifeLaw(p, "linear", rate=rate)


def _pow(p: str, amp: float, ref: float, m: float) -> LifeLaw:
    return LifeLaw(p, "power", amplitude=amp, reference=ref, exponent=m)


def _exp(p: str, amp: float, tau: float) -> LifeLaw:
    return LifeLaw(p, "exponential", amplitude=amp, time_constant=tau)


def _step(p: str, size: float, at: float) -> LifeLaw:
    return LifeLaw(p, "step", size=size, at=at)


def _const(p: str, v: float) -> LifeLaw:
    return LifeLaw(p, "constant", value=v)


def reference_life() -> ChallengeLife:
    """The shipped ``aging`` scenario's laws (the baseline's alarm threshold is calibrated on it)."""
    return ChallengeLife("aging", (_lin("k3", -2e-4), _pow("alpha_h", 0.15, 1200, 1.5), _lin("beta_h", -1e-4)),
                         visits=16, interval=100.0, seed=1)


def _smoke_lives() -> list[ChallengeLife]:
    """One life per kind that ``make test`` affords (< 60 s on two workers): a linear α_h life, a stable one, a
    sudden k3 loss, and a leakage life with few visits (the cause found by diagnose, G_leak trended)."""
    return [
        ChallengeLife("linear-alpha-fast", (_lin("alpha_h", 2.5e-4), _lin("k3", -1e-4)), visits=8, interval=100.0,
                      seed=11),
        ChallengeLife("stable-fast", (_const("k3", -0.03),), visits=5, kind="stable", seed=12, group="stable"),
        ChallengeLife("sudden-k3-fast", (_step("k3", -0.15, 330.0),), visits=7, kind="sudden", step_hours=330.0,
                      step_parameter="k3", seed=13, group="sudden"),
        _leakage("leakage-fast", 6e-7, 200.0, 8, seed=14),
    ]


def _leakage(name: str, rate: float, interval: float, visits: int, seed: int) -> ChallengeLife:
    """G_leak (S) rising linearly at ``rate`` S/h from a tight patch; the laminate itself nominal."""
    return ChallengeLife(name, (LifeLaw("G_leak", "linear", rate=rate),), visits=visits, interval=interval,
                         noise_m=2e-6, seed=seed, effects=("dielectric_leakage",), group="effect")


def _new_lives() -> list[ChallengeLife]:
    """Issue 28's lives: an effect degrading, few visits, laws outside the candidate laws."""
    lives = [
        _leakage("leakage-4e-7Sph-every200h", 4e-7, 200.0, 12, seed=301),
        _leakage("leakage-6e-7Sph-every100h", 6e-7, 100.0, 15, seed=302),
        _leakage("leakage-3.5e-7Sph-every200h", 3.5e-7, 200.0, 13, seed=303),
        _leakage("leakage-1e-6Sph-every100h", 1e-6, 100.0, 10, seed=304),
    ]
    lives.append(ChallengeLife("k2-loss-with-alpha-power", (_lin("k2", -1.5e-4), _pow("alpha_h", 0.15, 1300.0, 1.5)),
                               visits=15, interval=100.0, noise_m=2e-6, seed=305, group="other-section"))
    i = 310
    for name, laws, visits in (
            ("few-power-m1.6-every400h", (_pow("alpha_h", 0.15, 1900.0, 1.6),), 7),
            ("few-linear-every400h", (_lin("alpha_h", 1.0e-4), _lin("k3", -1e-4)), 6),
            ("few-exponential-every400h", (_exp("alpha_h", 0.03, 900.0),), 6),
            ("few-power-m2-every400h-k3", (_pow("alpha_h", 0.15, 2200.0, 2.0), _lin("k3", -1.5e-4)), 8)):
        i += 1
        lives.append(ChallengeLife(name, laws, visits=visits, interval=400.0, noise_m=2e-6, seed=i,
                                   group="few-visits"))
    odd: tuple[tuple[str, tuple[LifeLaw | LogisticLaw, ...], int, float], ...] = (
            ("logistic-mid1800-w400", (LogisticLaw("alpha_h", 0.30, 1800.0, 400.0),), 22, 100.0),
            ("logistic-mid1200-w300-every200h", (LogisticLaw("alpha_h", 0.25, 1200.0, 300.0),), 10, 200.0),
            ("two-stage-wear-knee1000h", (_lin("alpha_h", 2e-5), LifeLaw("alpha_h", "linear", rate=8e-5,
                                                                          start=1000.0)), 26, 100.0),
            ("two-stage-wear-knee600h-every200h", (_lin("alpha_h", 3e-5), LifeLaw("alpha_h", "linear", rate=1.2e-4,
                                                                                   start=600.0)), 12, 200.0),
            # added after the logistic and two-stage laws were built, not used to tune them: α_h falling along a
            # logistic to the lower trip limit, and a knee between two visits
            ("logistic-decreasing-mid1400-w350", (LogisticLaw("alpha_h", -0.20, 1400.0, 350.0),), 16, 100.0),
            ("two-stage-wear-knee750h", (_lin("alpha_h", 3e-5), LifeLaw("alpha_h", "linear", rate=1.0e-4,
                                                                         start=750.0)), 20, 100.0))
    for name, laws_, visits, interval in odd:
        i += 1
        lives.append(ChallengeLife(name, laws_, visits=visits, interval=interval, noise_m=2e-6, seed=i,
                                   group="out-of-family"))
    return lives


def challenge_lives(size: str = "full", per_group: int | None = None) -> list[ChallengeLife]:
    """The challenge's lives: ``size`` "smoke" (``make test``) or "full" (the bench); ``per_group`` keeps the first
    that many lives of each group (a reduced run of the full challenge)."""
    if size not in ("smoke", "full"):
        raise ValueError(f"challenge size must be 'smoke' or 'full', got {size!r}")
    lives = _smoke_lives() if size == "smoke" else _core_lives() + _new_lives()
    if per_group is None:
        return lives
    count: dict[str, int] = {}
    kept = []
    for life in lives:
        count[life.group] = count.get(life.group, 0) + 1
        if count[life.group] <= per_group:
            kept.append(life)
    return kept


def _core_lives() -> list[ChallengeLife]:
    """The original challenge: the monitor's parameters along the candidate laws, stable lives, sudden damage."""
    lives = [reference_life()]
    i = 100
    for m, ref in ((1.2, 1000.0), (2.0, 1400.0), (1.5, 900.0)):
        for noise in (2e-6, 5e-6):
            i += 1
            lives.append(ChallengeLife(f"power-m{m:g}-ref{ref:g}-n{noise * 1e6:g}um",
                                       (_pow("alpha_h", 0.15, ref, m), _lin("k3", -1.5e-4)), visits=16,
                                       interval=100.0, noise_m=noise, seed=i))
    for rate, interval in ((1.2e-4, 100.0), (2.5e-4, 50.0), (0.6e-4, 200.0)):
        i += 1
        lives.append(ChallengeLife(f"linear-{rate * 100:g}per100h-every{interval:g}h",
                                   (_lin("alpha_h", rate), _lin("beta_h", -1e-4)), visits=18, interval=interval,
                                   noise_m=5e-6, seed=i))
    for tau in (500.0, 700.0):
        i += 1
        lives.append(ChallengeLife(f"exponential-tau{tau:g}", (_exp("alpha_h", 0.02, tau), _lin("k3", -1e-4)),
                                   visits=18, interval=100.0, noise_m=2e-6, seed=i))
    i += 1
    lives.append(ChallengeLife("decreasing-alpha", (_lin("alpha_h", -1.0e-4), _lin("k3", -2e-4)), visits=16,
                               interval=100.0, noise_m=2e-6, seed=i))
    for rep in (1, 2):
        for noise in (2e-6, 5e-6, 10e-6):
            for c in (-0.03, 0.0, 0.02):
                i += 1
                lives.append(ChallengeLife(f"stable-k3{c:+g}-n{noise * 1e6:g}um-{rep}",
                                           (_const("k3", c), _const("beta_h", -c)), visits=10, interval=100.0,
                                           noise_m=noise, kind="stable", seed=i, group="stable"))
    for p, size, at in (("k3", -0.15, 450.0), ("k3", -0.10, 730.0), ("alpha_h", 0.05, 520.0),
                        ("beta_h", -0.2, 360.0), ("alpha_h", -0.04, 610.0)):
        i += 1
        lives.append(ChallengeLife(f"sudden-{p}{size:+g}-at{at:g}h", (_step(p, size, at),), visits=10,
                                   interval=100.0, noise_m=2e-6, kind="sudden", step_hours=at, step_parameter=p,
                                   seed=i, group="sudden"))
    return lives


