"""The board's regimes as a documented transition table and one pure step function.

``step(state, inputs, tick, config) -> (next_state, outputs, events)``: no clock, no I/O, no hidden state. The
supervisory counters (consecutive link failures, wake debounce, quiet time, ...) live in :class:`RegimeState`, so a
sequence of :class:`TickInputs` replays to the same regimes, tick for tick.

Regimes (seed paper, Introduction):

* ``STANDBY_HARVEST`` — board asleep, patches charge the battery; the wake comparator watches |patch voltage| and
  |base acceleration| against ``[wake]`` thresholds.
* ``SENSING`` — woken by a relevant or abnormal load: usage acquisition at 100 Hz; back to stand-by after
  ``[sensing] quiet_period`` with both comparator inputs below threshold.
* ``MAINTENANCE`` — external HV equipment present (for ``[maintenance] hv_debounce``): MBIT.a and MBIT.b run
  through the link with the condition monitor; leaves when the equipment is removed.
* ``SAFE`` — link lost, limit violation, sensor fault, tick overruns, or a brown-out during maintenance: zero
  actuation demand; leaves only on an explicit re-arm (the operator's, or the supervisor's after a link-loss-only
  SAFE once the link has been healthy for ``[safe] link_recovery``), refused while any cause persists.

Each tick the rows of :data:`TRANSITIONS` whose source is the current regime are tried in priority order (lowest
number first); the first whose condition holds fires. A row carries its trigger's condition (``when``), a pure
function of the tick (:class:`TickView`: the counted state, the inputs, the tick and its time, the timers), so a new
rule is a :class:`Trigger`, its condition and its row. Nothing else changes the regime: a test checks every observed
change against the table, and ``docs/board.md`` prints the table from this module.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import NamedTuple, TypeAlias

from board_config.board import BoardConfig
from firmware_sim.events import BoardEvent


class Regime(StrEnum):
    STANDBY_HARVEST = "STANDBY_HARVEST"
    SENSING = "SENSING"
    MAINTENANCE = "MAINTENANCE"
    SAFE = "SAFE"


#: integer codes for traces and plots
REGIME_CODES: dict[Regime, int] = {Regime.STANDBY_HARVEST: 0, Regime.SENSING: 1, Regime.MAINTENANCE: 2, Regime.SAFE: 3}


class Trigger(StrEnum):
    """Conditions that fire transitions (evaluated after this tick's counters are updated)."""

    LINK_LOST = "link_lost"  # link_fail >= [tick] link_loss_ticks consecutive failed exchanges
    SENSOR_FAULT = "sensor_fault"  # sample NaN/Inf, implausible, flagged by the rig, or sequence frozen
    LIMIT_VIOLATION = "limit_violation"  # a demand outside Table 1 was caught (clamped) or the rig refused one
    OVERRUN = "overrun"  # >= [tick] overrun_ticks consecutive missed tick deadlines
    BROWNOUT = "brownout"  # the power manager declares a brown-out
    HV_PRESENT = "hv_present"  # HV equipment present for [maintenance] hv_debounce, and energy to wake
    WAKE = "wake"  # comparator above threshold for [wake] debounce_ticks, and energy to wake
    QUIET = "quiet"  # comparator below both thresholds for [sensing] quiet_period
    HV_REMOVED = "hv_removed"  # HV equipment absent for [maintenance] hv_debounce
    REARM = "rearm"  # operator re-arm accepted (no cause of SAFE persists)
    LINK_RECOVERED = "link_recovered"  # SAFE caused by link loss only, link healthy for [safe] link_recovery


class TickInputs(NamedTuple):
    """This tick's percepts (computed by the board from the link sample, the power manager and the scheduler)."""

    sample_ok: bool = True  # the link delivered a sample this tick
    sensor_fault: bool = False  # the sample is invalid (only meaningful with sample_ok)
    limit_violation: bool = False  # a demand outside Table 1 was caught, or the rig refused one
    overrun: bool = False  # the previous tick missed its deadline
    wake_signal: bool = False  # the comparator sees |v_patch| or |z0dd| at or above its threshold
    hv_present: bool = False  # the rig reports HV equipment connected
    energy_ok: bool = True  # the battery can afford waking (power manager)
    brownout: bool = False  # brown-out in force (power manager)
    rearm: bool = False  # the operator asks to re-arm this tick


class RegimeState(NamedTuple):
    """Regime and supervisory counters (ticks)."""

    regime: Regime = Regime.STANDBY_HARVEST
    entered_tick: int = 0
    link_fail: int = 0  # consecutive failed exchanges
    link_ok: int = 0  # consecutive good exchanges
    overruns: int = 0  # consecutive missed deadlines
    wake_run: int = 0  # consecutive ticks with the comparator above threshold
    quiet_run: int = 0  # consecutive ticks with the comparator below threshold
    hv_run: int = 0  # consecutive ticks with HV present
    hv_off_run: int = 0  # consecutive ticks with HV absent
    safe_causes: tuple[str, ...] = ()  # what put (and kept) the board in SAFE


class RegimeOutputs(NamedTuple):
    regime: Regime
    actuation_allowed: bool  # only MAINTENANCE may command a non-zero voltage
    changed: bool
    trigger: Trigger | None


@dataclass(frozen=True)
class RegimeTimers:
    """The configuration turned into tick counts (computed once)."""

    link_loss: int
    overrun: int
    wake_debounce: int
    quiet: int
    hv_debounce: int
    link_recovery: int  # 0 = disabled
    period: float  # tick period (s)

    @classmethod
    def from_config(cls, cfg: BoardConfig) -> RegimeTimers:
        return cls(
            link_loss=cfg.tick_link_loss_ticks,
            overrun=cfg.tick_overrun_ticks,
            wake_debounce=cfg.wake_debounce_ticks,
            quiet=max(1, cfg.ticks(cfg.sensing_quiet_period)),
            hv_debounce=max(1, cfg.ticks(cfg.maintenance_hv_debounce)),
            link_recovery=cfg.ticks(cfg.safe_link_recovery),  # 0 s -> 0 ticks: disabled
            period=cfg.tick_period,
        )


class TickView(NamedTuple):
    """What a rule's condition sees: the state with this tick's counters already counted (the regime still the one
    the tick started in), this tick's inputs, the tick number, its time ``now = tick * period`` (s) and the timers."""

    state: RegimeState
    inputs: TickInputs
    tick: int
    now: float
    timers: RegimeTimers


class Refused(NamedTuple):
    """A condition's answer "does not fire, and say why": the incident (``incident``, ``detail``) is logged."""

    incident: str
    detail: str


#: a rule's condition: a pure function of the tick (True: the row fires; False or a refusal: it does not)
Condition: TypeAlias = Callable[[TickView], "bool | Refused"]


# --- the conditions of the triggers (each a pure function of the tick) --------------------------------------------
def link_lost(v: TickView) -> bool:
    """``[tick] link_loss_ticks`` consecutive failed exchanges."""
    return v.state.link_fail >= v.timers.link_loss


def sensor_fault(v: TickView) -> bool:
    """A sample arrived and it is invalid."""
    return v.inputs.sample_ok and v.inputs.sensor_fault


def limit_violation(v: TickView) -> bool:
    return v.inputs.limit_violation


def overrun(v: TickView) -> bool:
    """``[tick] overrun_ticks`` consecutive missed deadlines."""
    return v.state.overruns >= v.timers.overrun


#: the fault triggers and their conditions, in the table's priority order
FAULT_CONDITIONS: tuple[tuple[Trigger, Condition], ...] = (
    (Trigger.LINK_LOST, link_lost), (Trigger.SENSOR_FAULT, sensor_fault),
    (Trigger.LIMIT_VIOLATION, limit_violation), (Trigger.OVERRUN, overrun))


def fault_causes(v: TickView) -> list[Trigger]:
    """The fault triggers that hold this tick (what SAFE latches)."""
    return [trigger for trigger, holds in FAULT_CONDITIONS if holds(v)]


def brownout(v: TickView) -> bool:
    return v.inputs.brownout


def _debounced_wake(run: int, debounce: int, refused: bool, why_refused: str) -> bool | Refused:
    """A wake request (HV present, the wake comparator) held for ``run`` ticks fires once it has lasted ``debounce``
    ticks, unless ``refused``; a refused request is logged once per episode (when its run reaches ``debounce``)."""
    if refused and run == debounce:
        return Refused("wake_refused", why_refused)
    return run >= debounce and not refused


def _unaffordable(inputs: TickInputs) -> bool:
    """Waking would cost what the battery cannot give."""
    return not inputs.energy_ok or inputs.brownout


def hv_present(v: TickView) -> bool | Refused:
    """HV present for ``[maintenance] hv_debounce``; from stand-by only with the energy to wake."""
    return _debounced_wake(v.state.hv_run, v.timers.hv_debounce,
                           v.state.regime is Regime.STANDBY_HARVEST and _unaffordable(v.inputs),
                           "HV equipment present but the battery cannot afford waking into MAINTENANCE")


def hv_removed(v: TickView) -> bool:
    return v.state.hv_off_run >= v.timers.hv_debounce


def wake(v: TickView) -> bool | Refused:
    """The comparator above threshold for ``[wake] debounce_ticks``, with the energy to wake."""
    return _debounced_wake(v.state.wake_run, v.timers.wake_debounce, _unaffordable(v.inputs),
                           "wake comparator fired but the battery cannot afford waking (below wake_min_voltage or "
                           "brown-out)")


def quiet(v: TickView) -> bool:
    return v.state.quiet_run >= v.timers.quiet


def link_recovered(v: TickView) -> bool:
    """SAFE latched for link loss only, the link healthy for ``[safe] link_recovery`` (> 0), nothing else wrong."""
    tm = v.timers
    return (tm.link_recovery > 0 and v.state.link_ok >= tm.link_recovery
            and all(c == Trigger.LINK_LOST.value for c in v.state.safe_causes)
            and not fault_causes(v) and not v.inputs.brownout)


def rearm_blockers(v: TickView) -> list[str]:
    """What refuses an operator re-arm this tick: a fault cause, no sample, a brown-out (empty: re-arm)."""
    blockers = [c.value for c in fault_causes(v)]
    if not v.inputs.sample_ok:
        blockers.append("no sample")
    if v.inputs.brownout:
        blockers.append("brownout")
    return blockers


def rearm(v: TickView) -> bool | Refused:
    """The operator asks to re-arm and no cause of SAFE persists (else the refusal is logged)."""
    if not v.inputs.rearm:
        return False
    persisting = rearm_blockers(v)
    if persisting:
        return Refused("rearm_refused", "re-arm refused: " + ", ".join(persisting))
    return True


@dataclass(frozen=True)
class Transition:
    """One row of the transition table: in ``source``, when ``when`` holds, go to ``target``."""

    source: Regime
    trigger: Trigger
    target: Regime
    priority: int
    guard: str  # what must hold besides the trigger (documentation; enforced in the trigger's condition)
    action: str  # what the board does on this transition
    when: Condition  # the trigger's condition (a pure function of the tick)


S, SE, M, X = Regime.STANDBY_HARVEST, Regime.SENSING, Regime.MAINTENANCE, Regime.SAFE
_FAULT_ACTION = "zero demand; abort MBIT/usage episode (logged); latch the cause"

#: The transition table. Every regime change the board can make is one of these rows.
TRANSITIONS: tuple[Transition, ...] = (
    # faults: every non-SAFE regime
    *(Transition(src, trig, X, prio, "", _FAULT_ACTION, holds)
      for prio, (trig, holds) in enumerate(FAULT_CONDITIONS, start=1) for src in (S, SE, M)),
    # brown-out: actuation must stop (SAFE) during maintenance; forced stand-by from sensing
    Transition(M, Trigger.BROWNOUT, X, 5, "", "zero demand; MBIT aborted (logged INCOMPLETE)", brownout),
    Transition(SE, Trigger.BROWNOUT, S, 5, "", "close the usage episode (summary logged, reason brownout)", brownout),
    # maintenance
    Transition(S, Trigger.HV_PRESENT, M, 6, "battery >= wake_min_voltage, no brown-out",
               "start the MBIT sequence (settle, MBIT.a, settle, MBIT.b)", hv_present),
    Transition(SE, Trigger.HV_PRESENT, M, 6, "", "close the usage episode; start the MBIT sequence", hv_present),
    Transition(M, Trigger.HV_REMOVED, S, 7, "", "zero demand; an unfinished MBIT is logged INCOMPLETE", hv_removed),
    # flight
    Transition(S, Trigger.WAKE, SE, 8, "battery >= wake_min_voltage, no brown-out (else 'wake_refused' logged)",
               "open a usage episode", wake),
    Transition(SE, Trigger.QUIET, S, 9, "", "close the usage episode (summary logged)", quiet),
    # leaving SAFE
    Transition(X, Trigger.LINK_RECOVERED, S, 10, "SAFE was caused by link loss only; [safe] link_recovery > 0",
               "supervisor re-arm (logged)", link_recovered),
    Transition(X, Trigger.REARM, S, 11, "link up, sample valid, no limit violation, no brown-out, no overrun "
               "(else 'rearm_refused' logged)",
               "operator re-arm (logged)", rearm),
)


def _rows_by_source() -> dict[Regime, tuple[Transition, ...]]:
    """The rows per source regime in priority order (the order :func:`step_full` tries them)."""
    return {r: tuple(sorted((t for t in TRANSITIONS if t.source is r), key=lambda t: t.priority)) for r in Regime}


_ROWS = _rows_by_source()
ALLOWED: frozenset[tuple[Regime, Regime]] = frozenset((t.source, t.target) for t in TRANSITIONS)


#: the percepts of an uneventful tick (a good sample, nothing above threshold, no request)
_NOMINAL_INPUTS = (TickInputs(), TickInputs(energy_ok=False))
_STANDBY_OUT = RegimeOutputs(Regime.STANDBY_HARVEST, False, False, None)


def step(state: RegimeState, inputs: TickInputs, tick: int, timers: RegimeTimers
         ) -> tuple[RegimeState, RegimeOutputs, tuple[BoardEvent, ...]]:
    """One tick of the regime machine. ``tick`` is the board's tick number; its time is ``tick * timers.period``.

    The counters saturate just above the value any trigger compares them with, so an uneventful stand-by tick
    leaves the state unchanged; that case returns the same state at once (same result as the full evaluation, which
    a test checks against :func:`step_full`). Settled means the three "good" runs at their saturation value and no
    overrun counted; the other counters are then zero: ``link_ok >= 1`` means the last exchange worked
    (``link_fail = 0``), ``quiet_run >= 1`` that the comparator was last below threshold (``wake_run = 0``),
    ``hv_off_run >= 1`` that HV was last absent (``hv_run = 0``).
    """
    if inputs in _NOMINAL_INPUTS and settled_standby(state, timers):
        return state, _STANDBY_OUT, ()
    return step_full(state, inputs, tick, timers)


def settled_standby(state: RegimeState, timers: RegimeTimers) -> bool:
    """Whether ``state`` is settled stand-by: an uneventful tick (a good sample, nothing above threshold, no
    request; with or without energy to wake) leaves it exactly as it is (see :func:`step`)."""
    return (state.regime is Regime.STANDBY_HARVEST and state.overruns == 0 and state.quiet_run == timers.quiet
            and state.hv_off_run == timers.hv_debounce and state.link_ok == max(timers.link_recovery, 1))


def quiet_standby(state: RegimeState, timers: RegimeTimers, m: int) -> RegimeState | None:
    """The state after ``m >= 1`` uneventful ticks (a good sample, nothing above threshold, no HV, no request; with
    or without energy to wake) from stand-by: no row of the table can fire (the fault counters fall to zero, the
    wake and HV runs stay zero), no event is logged, and only the good runs count up to their saturation — the same
    as ``m`` calls of :func:`step` (a test checks it). None outside stand-by."""
    if state.regime is not Regime.STANDBY_HARVEST or m < 1 or timers.link_loss < 1 or timers.overrun < 1:
        return None
    return RegimeState(state.regime, state.entered_tick, 0, min(state.link_ok + m, max(timers.link_recovery, 1)), 0,
                       0, min(state.quiet_run + m, timers.quiet), 0, min(state.hv_off_run + m, timers.hv_debounce),
                       state.safe_causes)


def quiet_awake(state: RegimeState, timers: RegimeTimers, wake: Sequence[bool]) -> tuple[RegimeState, int]:
    """SENSING without HV, or MAINTENANCE with HV present, over ticks with a good sample, no request and no
    brown-out, the comparator above threshold or not (``wake``, one flag per tick): the state after the leading
    ticks before one where a row fires — in SENSING ``quiet`` (that tick is not taken); in MAINTENANCE none can —
    and how many were taken. The same as as many calls of :func:`step` (a test checks it); no event is logged.
    ``(state, 0)`` in another regime."""
    regime = state.regime
    if regime is not Regime.SENSING and regime is not Regime.MAINTENANCE:
        return state, 0
    if timers.link_loss < 1 or timers.overrun < 1:
        return state, 0
    wake_max = timers.wake_debounce + 1
    quiet_max = timers.quiet
    stops = regime is Regime.SENSING  # quiet fires there (in MAINTENANCE HV stays: hv_removed cannot)
    wake_run, quiet_run = state.wake_run, state.quiet_run
    m = 0
    for w in wake:
        if w:
            wr, qr = min(wake_run + 1, wake_max), 0
        else:
            wr, qr = 0, min(quiet_run + 1, quiet_max)
        if stops and qr >= quiet_max:
            break
        wake_run, quiet_run = wr, qr
        m += 1
    if m == 0:
        return state, 0
    link_ok = min(state.link_ok + m, max(timers.link_recovery, 1))
    if stops:
        hv_run, hv_off_run = 0, min(state.hv_off_run + m, timers.hv_debounce)
    else:
        hv_run, hv_off_run = min(state.hv_run + m, timers.hv_debounce + 1), 0
    return RegimeState(regime, state.entered_tick, 0, link_ok, 0, wake_run, quiet_run, hv_run, hv_off_run,
                       state.safe_causes), m


def step_full(state: RegimeState, inputs: TickInputs, tick: int, timers: RegimeTimers
              ) -> tuple[RegimeState, RegimeOutputs, tuple[BoardEvent, ...]]:
    """:func:`step` without the stand-by shortcut (the reference the shortcut is tested against): count this tick,
    then try the rows of :data:`TRANSITIONS` from the current regime in priority order; the first whose condition
    holds fires."""
    now = tick * timers.period
    ok = inputs.sample_ok
    link_fail = 0 if ok else min(state.link_fail + 1, timers.link_loss)
    link_ok = min(state.link_ok + 1, max(timers.link_recovery, 1)) if ok else 0
    overruns = min(state.overruns + 1, timers.overrun) if inputs.overrun else 0
    wake = ok and inputs.wake_signal and not inputs.sensor_fault
    wake_run = min(state.wake_run + 1, timers.wake_debounce + 1) if wake else 0
    quiet_run = min(state.quiet_run + 1, timers.quiet) if (ok and not wake) else (0 if wake else state.quiet_run)
    hv_run = min(state.hv_run + 1, timers.hv_debounce + 1) if (ok and inputs.hv_present) else 0
    hv_off_run = (min(state.hv_off_run + 1, timers.hv_debounce) if (ok and not inputs.hv_present)
                  else (0 if ok else state.hv_off_run))
    regime = state.regime
    st = RegimeState(regime, state.entered_tick, link_fail, link_ok, overruns, wake_run, quiet_run, hv_run,
                     hv_off_run, state.safe_causes)
    view = TickView(st, inputs, tick, now, timers)

    events: list[BoardEvent] = []
    fired: Transition | None = None
    for row in _ROWS[regime]:
        hit = row.when(view)
        if hit is True:
            fired = row
            break
        if hit is not False:  # a refusal: the row does not fire, the incident is logged
            events.append(BoardEvent("incident", tick, now, {"incident": hit.incident, "detail": hit.detail}))

    if fired is None:
        if regime is Regime.SAFE:  # stay in SAFE, accumulating any new cause (SAFE has no fault rows)
            new = [c.value for c in fault_causes(view) if c.value not in st.safe_causes]
            if new:
                st = st._replace(safe_causes=st.safe_causes + tuple(new))
        return st, RegimeOutputs(regime, regime is Regime.MAINTENANCE, False, None), tuple(events)

    target = fired.target
    safe_causes: tuple[str, ...] = ()
    if target is Regime.SAFE:  # every fault cause at once; a brown-out (no fault cause, else a fault row fired) alone
        causes = fault_causes(view)
        safe_causes = tuple(c.value for c in (causes or [fired.trigger]))
    st = RegimeState(target, tick, link_fail, link_ok, overruns, 0 if target is Regime.SENSING else wake_run,
                     0, hv_run, hv_off_run, safe_causes)
    events.append(BoardEvent("regime_change", tick, now, {
        "from_regime": regime.value, "to_regime": target.value, "trigger": fired.trigger.value,
        "causes": list(safe_causes)}))
    return st, RegimeOutputs(target, target is Regime.MAINTENANCE, True, fired.trigger), tuple(events)


def transition_table_markdown() -> str:
    """The transition table as a Markdown table (docs/board.md prints this)."""
    lines = ["| from | trigger | to | priority | guard | action |", "| --- | --- | --- | --- | --- | --- |"]
    for t in sorted(TRANSITIONS, key=lambda t: (list(Regime).index(t.source), t.priority)):
        lines.append(f"| {t.source.value} | `{t.trigger.value}` | {t.target.value} | {t.priority} | "
                     f"{t.guard or '—'} | {t.action} |")
    return "\n".join(lines)


def is_allowed(source: Regime, target: Regime) -> bool:
    return (source, target) in ALLOWED
