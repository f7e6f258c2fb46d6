"""What ``shm discover`` returns: :class:`Discovery` with its kept terms (:class:`FoundTerm`), the screen table
(:class:`ScreenRow`), and :class:`DiscoverError`."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from workbench.discover._dictionary import ALL_FORMS, DELAY_FORMS, Term
from workbench.discover._effect_writer import emit_effect_source, parameter_names_for
from workbench.discover._gates import TIME_GATES
from workbench.fit import FitError, FitOutcome, Target


class DiscoverError(FitError):
    """Discovery cannot start (bad records or effects)."""


#: a residual below this fraction of a channel's range is the simulation's own accuracy (integration rtol 1e-6,
#: ten times over), not a model error: a noise-free record that the model matches this well has nothing to find
NUMERICAL_MATCH_OF_RANGE = 1e-5


def noise_free_match(targets: Sequence[Target], held_sigma: float) -> bool:
    """True when the held-out residual of every channel of every record is below :data:`NUMERICAL_MATCH_OF_RANGE`
    of the channel's range (bounded from the RMS over all channels, ``held_sigma`` in each channel's σ): the model
    matches a noise-free record numerically, and any term found would fit the integrator's rounding (issue 33: a
    noiseless nominal record 'found' a term, with more than 100 % of the excess removed)."""
    if not targets:
        return False
    for tg in targets:
        span = np.ptp(tg.measured, axis=1)
        bound = held_sigma * math.sqrt(sum(len(t.channels) for t in targets)) * tg.sigma
        if not np.all(bound <= NUMERICAL_MATCH_OF_RANGE * span):
            return False
    return True


def excess_share_removed(before_sigma: float, after_sigma: float, tolerance: float) -> float | None:
    """The share of the excess over the noise (RMS² − 1, σ²) that going from ``before_sigma`` to ``after_sigma``
    removes, at most 1 (what falls below the noise floor removes no more than the whole excess); None when
    ``before_sigma`` is within ``tolerance`` of the floor: no meaningful excess to take a share of."""
    if not before_sigma > 1.0 + tolerance:
        return None
    before, after = before_sigma ** 2 - 1.0, max(after_sigma ** 2 - 1.0, 0.0)
    return (before - after) / before


@dataclass
class FoundTerm:
    """A kept term: its fitted coefficient and shape, its size along the records, and what it means."""

    term: Term
    coef: float
    shape: float
    scale: float
    words: str
    #: terms that explain these records as well, within the noise (key, words, held-out RMS σ, how it was judged)
    twins: list[dict[str, Any]] = field(default_factory=list)
    #: the shape's standard error (an onset time's, s), None when not fitted
    shape_se: float | None = None
    #: the key of the kept term whose words already say this one (a finite change's end, said by its rise), else ""
    said_with: str = ""

    @property
    def description(self) -> str:
        """The words, and what the records cannot tell it from (with the test that would) — in the same sentence: a
        finding whose place or kind the records leave open is said to be open where it is first stated (a crack in
        section 1 or 2 on a quasi-static record), not one sentence later."""
        if not self.twins:
            return self.words
        return (self.words + " — these records cannot tell it from "
                + "; or from ".join(t["words"] for t in self.twins) + " (" + separating_test(self.term, self.twins)
                + ")")

    def to_dict(self) -> dict[str, Any]:
        return {"key": self.term.key, "placement": self.term.placement, "index": self.term.index,
                "signal": self.term.signal, "form": self.term.form, "coefficient": self.coef,
                "coefficient_unit": self.term.unit, "shape": self.shape if ALL_FORMS[self.term.form].shape else None,
                "edge_width_s": self.term.width or None, "since_s": self.term.since, "signal_scale": self.scale,
                "words": self.words,
                "twins": self.twins,
                "description": self.description, "said_with": self.said_with}


def in_one_sentence(found: Sequence[FoundTerm]) -> str:
    """What was found, for a verdict's first sentence: each kept term's description joined by "; and", leaving out
    those another term's words already say (a finite change's end)."""
    return "; and ".join(f.description for f in found if not f.said_with)


def separating_test(term: Term, twins: Sequence[dict[str, Any]]) -> str:
    """The record that would tell ``term`` from its ``twins``, in words."""
    places = {term.placement, *(t["placement"] for t in twins)}
    tests = []
    if "drive" in places and "measurement" in places:
        tests.append("record the patch voltage: a lag before the patches shows in it, a lag in the laser does not")
    if len({(term.placement, term.index), *((t["placement"], t["index"]) for t in twins)}) > 1 and \
            places <= {"force_mass", "force_section"}:
        tests.append("a sweep through the modes tells the masses and sections apart")
    shaped = {"pos", "neg", "square", "cube", "sat"}  # forms whose shape a record's amplitude range decides
    if (term.signal == "va" and term.form in shaped) or any(t["signal"] == "va" and t["form"] in shaped
                                                             for t in twins):
        tests.append("drive both signs and several amplitudes")
    if {term.form, *(t["form"] for t in twins)} & shaped and \
            places <= {"measurement", "force_mass", "force_section"} and len(places) > 1:
        tests.append("a static calibration of the laser against a reference tells a sensor map from a force")
    timed = [f in TIME_GATES for f in (term.form, *(t["form"] for t in twins))]
    if any(timed) and not all(timed):  # an event against a form constant in time
        tests.append("a second record long after the first, moving the section both ways, tells a change at an "
                     "instant (it stays) from one with the motion's sign or size (it comes and goes)")
    if not tests:
        tests.append("a record that reaches larger amplitudes and sweeps through the modes would")
    return "; ".join(tests)


@dataclass
class ScreenRow:
    """A screened term: its coefficient and the errors it leaves; ``shape``: the shape it was probed at when not the
    term's own (an onset found in the residual)."""

    term: Term
    coef: float
    held_rms_sigma: float
    train_rms_sigma: float
    shape: float | None = None
    #: the onset ``shape`` is known (an event's instant, refitted elsewhere): the refit starts there, no scan
    placed: bool = False


@dataclass
class Discovery:
    """What ``shm discover`` found (``verdict``: ``found`` | ``partial`` | ``not_found``)."""

    verdict: str
    message: str
    terms: list[FoundTerm]
    train_before: float
    held_before: float
    train_after: float
    held_after: float
    screen: list[ScreenRow]
    n_terms_searched: int
    stable: bool
    stability_note: str
    records: list[str]
    outcome: FitOutcome | None
    targets: list[Target]
    n_sims: int
    timings: dict[str, float] = field(default_factory=dict)
    rounds: list[dict[str, Any]] = field(default_factory=list)

    def effect_source(self, class_name: str | None = None, effect_name: str = "discovered") -> str | None:
        """The readable effect module for the kept terms (None when nothing was found)."""
        if not self.terms:
            return None
        values: dict[str, float] = {}
        for ft, (cname, gname) in zip(self.terms, parameter_names_for([ft.term for ft in self.terms])):
            values[cname] = ft.coef
            if gname:
                values[gname] = ft.shape
        return emit_effect_source([ft.term for ft in self.terms], values, class_name=class_name,
                                  effect_name=effect_name, words=[ft.description for ft in self.terms],
                                  records=self.records, held_before=self.held_before, held_after=self.held_after)

    def to_dict(self) -> dict[str, Any]:
        return {
            "verdict": self.verdict, "message": self.message, "terms": [t.to_dict() for t in self.terms],
            "train_rms_sigma": {"before": self.train_before, "after": self.train_after},
            "held_rms_sigma": {"before": self.held_before, "after": self.held_after},
            "screen": [{"key": r.term.key, "placement": r.term.placement, "form": r.term.form, "signal": r.term.signal,
                        "coefficient": r.coef, "coefficient_unit": r.term.unit, "held_rms_sigma": r.held_rms_sigma,
                        "train_rms_sigma": r.train_rms_sigma} for r in self.screen],
            "terms_searched": self.n_terms_searched, "stable": self.stable, "stability": self.stability_note,
            "records": self.records, "simulations": self.n_sims, "timings_s": self.timings, "rounds": self.rounds,
        }


def describe_units(found: Sequence[FoundTerm]) -> list[str]:
    """One line per kept term: coefficient with unit and, for a shaped form, its shape."""
    out = []
    for f in found:
        line = f"{f.term.key}: coefficient {f.coef:.4g} {f.term.unit}"
        if ALL_FORMS[f.term.form].shape:
            unit = ("s" if f.term.form in (*DELAY_FORMS, *TIME_GATES) else
                    "m/s" if f.term.signal.startswith(("zd", "dd")) else "V" if f.term.signal in ("va", "vc")
                    else "A" if f.term.signal == "ic" else "m")
            line += f", {ALL_FORMS[f.term.form].shape} {f.shape:.4g} {unit}"
        if f.term.width > 0.0:
            line += f", edge width {f.term.width:.4g} s"
        elif f.term.width < 0.0:  # an accelerating ramp's growth time
            line += f", growth time {-f.term.width:.4g} s"
        if f.term.since is not None:  # a switched change begun during the record
            line += f", from t = {f.term.since:.4g} s"
        out.append(line)
    return out
