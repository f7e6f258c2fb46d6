"""The MAINTENANCE regime's work: the MBIT sequence, driven tick by tick through the link.

Sequence (``[maintenance] sequence`` of ``board.toml``, default MBIT.a then MBIT.b): a settle period at zero demand
(``[maintenance] settle``), the first MBIT's channel commands one per tick (``firmware_sim.mbit.generate_mbit``:
clamped to Table 1, a clamp is logged as an incident), a settle, the next MBIT, ..., then the maintenance verdict.

Model-based monitoring (seed paper Sec. 4): the board carries the *nominal* plant (parameter set of the board, the
amplifier terminal, no deviations). A visit's command sequence is fixed, so at its start the board integrates the
nominal model once over the whole plan — same commands, same linear slew between consecutive commands as the rig's
amplifier, delayed as the link delivers them — which is the trajectory lock-step stepping would give, with the same
history (hysteresis included) as the hardware. Each sample returned during an MBIT (the response to command ``j``)
goes to the condition monitor (``firmware_sim.condition_monitor``, Eq. 11 + fault counter) with ``z3_md``. The
monitor is reset before each MBIT; the verdict of an MBIT is FAULT if the counter latched, else PASS; the visit's
verdict is FAULT if any MBIT faulted, PASS if all passed, INCOMPLETE if the visit was cut short (HV removed, SAFE).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from board_config import MbitDefinition, MfcLimits, MonitorSettings
from board_config.errors import InputError
from firmware_sim.condition_monitor import ConditionMonitor
from firmware_sim.events import BoardEvent
from firmware_sim.mbit import MbitSequence, generate_mbit
from plant import InputSignals, PlantModel


@dataclass(frozen=True)
class _Step:
    kind: str  # "settle" | "mbit"
    ticks: int
    key: str = ""


class MaintenanceSequencer:
    """Runs the MBIT sequence for one maintenance visit. ``start``, then ``step`` once per tick, ``abort`` if cut."""

    def __init__(self, sequence: tuple[str, ...], definitions: Mapping[str, MbitDefinition], limits: MfcLimits,
                 monitor: MonitorSettings, nominal: PlantModel, settle_ticks: int, period: float) -> None:
        missing = [k for k in sequence if k not in definitions]
        if missing:
            raise InputError(f"maintenance sequence names MBIT {missing[0]!r}, which is not defined "
                             f"(defined: {', '.join(sorted(definitions))})")
        self.period = float(period)
        self.sequences: dict[str, MbitSequence] = {}
        for key in sequence:
            defn = definitions[key]
            if abs(defn.sample_rate * period - 1.0) > 1e-9:
                raise InputError(f"{defn.source}: mbit.{key}.sample_rate is {defn.sample_rate:g} Hz; the board plays "
                                 f"one command per tick ({1.0 / period:g} Hz)")
            self.sequences[key] = generate_mbit(defn, limits, on_clamp="report")
        self.plan: tuple[_Step, ...] = tuple(
            s for key in sequence for s in (_Step("settle", settle_ticks), _Step("mbit", len(self.sequences[key]), key))
            if s.ticks > 0)
        self.nominal = nominal
        self._i_z3 = nominal.output_names.index("z3")
        self.monitor = ConditionMonitor(monitor)
        self._ref: list[float] = []  # nominal z3 (m) after each step call of the visit
        self._ref_cache: list[float] | None = None  # the same for every visit: computed once (prepare())
        self._calls = 0
        self.active = False
        self.results: list[dict[str, Any]] = []
        self._i = 0  # index in plan
        self._j = 0  # tick within the current plan step
        self._cmd = (0.0, 0.0)  # last command sent (V)
        self._prev = (0.0, 0.0)  # the one before (V)
        self._z3_md = 0.0
        self._rows: list[tuple[float, float, float, float]] = []  # (t s, v_ch1 V, v_ch2 V, z3 m) of this visit
        self._mark = 0  # first row of the current MBIT's record (its preceding settle included)
        #: link delays (ticks) the monitor may attribute to the link: (0,) for a rig that answers with the state after
        #: the command acted (in-process, lock-step); (0, 1) for a real-time rig, whose sample precedes the command's
        #: action by one tick (see :meth:`set_link_lags`)
        self.lags: tuple[int, ...] = (0,)
        self._sse = [0.0]  # per lag: sum of squared residuals (m^2) over this visit's samples
        self.lag = 0  # the link delay (ticks) the monitor currently uses

    def set_link_lags(self, lags: tuple[int, ...]) -> None:
        """The link delays (ticks) to choose from; the visit's samples pick the one with the least squared residual
        so far (causal: each sample is judged with what was known when it arrived)."""
        if not lags or min(lags) < 0:
            raise ValueError(f"link lags must be non-negative ticks, got {lags!r}")
        self.lags = tuple(int(x) for x in lags)
        self._sse = [0.0] * len(self.lags)

    # --- lifecycle ----------------------------------------------------------------------------------
    def start(self, tick: int) -> list[BoardEvent]:
        """Begin a visit at ``tick``: nominal model at rest, first settle period, zero demand."""
        self._ref = self.prepare()
        self._calls = 0
        self._sse = [0.0] * len(self.lags)
        self.lag = self.lags[0]
        self.monitor.reset()
        self.active = True
        self.results = []
        self._i = 0
        self._j = 0
        self._cmd = self._prev = (0.0, 0.0)
        self._rows = []
        self._mark = 0
        events = []
        for _key, seq in self.sequences.items():
            if seq.clamp.clamped:
                events.append(BoardEvent("incident", tick, tick * self.period, {
                    "incident": "mbit_clamped", "detail": seq.clamp.message(seq.definition.label)}))
        return events

    @property
    def done(self) -> bool:
        return self._i >= len(self.plan)

    @property
    def current(self) -> str:
        """What the sequencer is doing: ``settle``, ``MBIT.a``, ..., ``done``."""
        if self.done:
            return "done"
        st = self.plan[self._i]
        return st.kind if st.kind == "settle" else self.sequences[st.key].definition.label

    @property
    def monitor_count(self) -> int:
        return self.monitor.count

    @property
    def z3_model(self) -> float:
        """The nominal model's tip displacement for the latest sample (m)."""
        return self._z3_md

    def step(self, tick: int, z3_meas: float) -> tuple[tuple[float, float], list[BoardEvent]]:
        """Take this tick's measured z3 (m; the response to the last command) and return the next command (V)."""
        events: list[BoardEvent] = []
        now = tick * self.period
        if not self.active:
            return (0.0, 0.0), events
        if self.done:
            return self._send((0.0, 0.0))
        # the visit's full-rate record: the command applied over the interval that ends now, and its response
        self._rows.append((now, self._cmd[0], self._cmd[1], z3_meas))
        # 1. the nominal model follows the command just applied by the rig (slew from the previous one)
        self._calls += 1
        if len(self.lags) > 1:
            self._z3_md = z3_md = self._model_with_lag(z3_meas)
        else:
            self._z3_md = z3_md = self._ref[max(self._calls - self.lags[0], 0)]
        st = self.plan[self._i]
        # 2. monitor the response during an MBIT (sample j answers command j-1 of this plan step)
        if st.kind == "mbit" and self._j > 0:
            self.monitor.update(now, z3_md, z3_meas)
            if self._j == st.ticks:
                events.append(self._record(tick, st.key))
                self._mark = len(self._rows)
                events.append(self._result(tick, st.key))
                self._i += 1
                self._j = 0
                if self.done:
                    events.append(self._verdict(tick, complete=True))
                    return self._send((0.0, 0.0), events)
                st = self.plan[self._i]
        elif st.kind == "settle" and self._j >= st.ticks:
            self._i += 1
            self._j = 0
            st = self.plan[self._i] if not self.done else st
        # 3. the next command
        if self.done:
            return self._send((0.0, 0.0), events)
        if st.kind == "mbit":
            if self._j == 0:
                self.monitor.reset()
                seq = self.sequences[st.key]
                events.append(BoardEvent("mbit_start", tick, now, {"mbit": st.key, "label": seq.definition.label}))
            cmd = self.sequences[st.key].command(self._j)
        else:
            cmd = (0.0, 0.0)
        self._j += 1
        return self._send(cmd, events)

    def _model_with_lag(self, z3_meas: float) -> float:
        """The nominal z3 (m) for this sample under the link delay with the least squared residual so far."""
        best = 0
        for i in range(1, len(self.lags)):
            if self._sse[i] < self._sse[best]:
                best = i
        self.lag = self.lags[best]
        z3_md = self._ref[max(self._calls - self.lag, 0)]
        if z3_meas == z3_meas:  # not NaN (a missing or invalid sample tells nothing about the delay)
            for i, lag in enumerate(self.lags):
                r = z3_meas - self._ref[max(self._calls - lag, 0)]
                self._sse[i] += r * r
        return z3_md

    def _send(self, cmd: tuple[float, float], events: list[BoardEvent] | None = None
              ) -> tuple[tuple[float, float], list[BoardEvent]]:
        self._prev = self._cmd
        self._cmd = cmd
        return cmd, events if events is not None else []

    def abort(self, tick: int, reason: str) -> list[BoardEvent]:
        """The visit is cut short (HV removed, SAFE): log the unfinished MBIT and an INCOMPLETE verdict."""
        if not self.active:
            return []
        events = []
        if not self.done:
            st = self.plan[self._i]
            ran, of = self._j * self.period, st.ticks * self.period
            events.append(BoardEvent("incident", tick, tick * self.period, {
                "incident": "mbit_aborted", "detail": f"{self.current} interrupted ({reason}) after {ran:.2f} s "
                                                      f"of {of:.2f} s"}))
            events.append(self._verdict(tick, complete=False, reason=reason))
        self.active = False
        return events

    def finish(self) -> None:
        self.active = False

    def commands(self) -> np.ndarray:
        """The visit's planned channel commands (V), one row (v_ch1, v_ch2) per step call, settles included."""
        rows = []
        for st in self.plan:
            if st.kind == "settle":
                rows.append(np.zeros((st.ticks, 2)))
            else:
                seq = self.sequences[st.key]
                rows.append(np.column_stack([seq.v_ch1, seq.v_ch2]))
        rows.append(np.zeros((1, 2)))  # the zero demand after the last MBIT
        return np.vstack(rows)

    def prepare(self) -> list[float]:
        """The visit's nominal reference (:meth:`_reference`), computed at the first call and kept: it depends only
        on the planned sequence and the nominal model, so every visit has the same. A paced run calls this before
        its first tick (:class:`firmware_sim.runner.BoardRunner`), so that a visit's first tick does no model run
        (tens of ms on a loaded machine: several missed tick deadlines in a row, and SAFE for an overrun)."""
        if self._ref_cache is None:
            self._ref_cache = self._reference()
        return self._ref_cache

    def _reference(self) -> list[float]:
        """The nominal model's z3 (m) after every step call of a visit, computed once at its start.

        Call ``c`` feeds the response over the interval in which the rig slewed from command ``c-2`` to command
        ``c-1`` (commands before the visit are 0 V); so the input is the command sequence delayed by two samples,
        linearly interpolated between ticks — exactly what stepping the model in lock-step would integrate.
        """
        cmds = self.commands()
        m = cmds.shape[0]
        u = np.zeros((1, m + 2, 3))
        u[0, 2:, 0:2] = cmds
        t_out = self.period * np.arange(m + 2)
        res = self.nominal.simulate(InputSignals(0.0, self.period, u), t_out=t_out, rtol=1e-6,
                                    h_max=min(5e-3, self.period), threads=1)
        res.raise_on_failure("nominal model failed on the MBIT sequence: ")
        ref: list[float] = res.y[0, :, self._i_z3].tolist()
        return ref

    # --- records --------------------------------------------------------------------------------------
    def _record(self, tick: int, key: str) -> BoardEvent:
        """The completed MBIT's full-rate drive and response (its preceding settle included) as an
        ``mbit_record`` event: ``rows`` of (board time s, v_ch1 V, v_ch2 V, z3 m) — the commands, reached at the
        end of each tick by the amplifier's linear slew, and the laser's response. Not stored in the usage log
        itself; a record writer (``studies.health.visit_records``) turns it into a measurement record file."""
        seq = self.sequences[key]
        return BoardEvent("mbit_record", tick, tick * self.period, {
            "mbit": key, "label": seq.definition.label, "test": f"mbit-{key}", "rate_Hz": 1.0 / self.period,
            "mbit_ticks": len(seq), "rows": tuple(self._rows[self._mark:])})

    def _result(self, tick: int, key: str) -> BoardEvent:
        st = self.monitor.state
        seq = self.sequences[key]
        rec = {
            "mbit": key, "label": seq.definition.label, "verdict": "FAULT" if st.fault else "PASS",
            "fault_time_s": st.fault_time, "max_count": st.max_count, "max_eps": st.max_eps,
            "n_samples": st.n_samples, "n_exceed": st.n_exceed, "n_invalid": st.n_invalid,
            "clamp_json": json.dumps(seq.clamp.describe()),
        }
        self.results.append(rec)
        return BoardEvent("mbit_result", tick, tick * self.period, rec)

    def _verdict(self, tick: int, complete: bool, reason: str = "") -> BoardEvent:
        labels = [r["label"] for r in self.results]
        faults = [r["label"] for r in self.results if r["verdict"] == "FAULT"]
        if faults:
            verdict = "FAULT"  # a fault found before an interruption still stands
        elif complete:
            verdict = "PASS"
        else:
            verdict = "INCOMPLETE"
        detail = (f"faults in {', '.join(faults)}" if faults else "no fault") + (
            "" if complete else f"; visit cut short ({reason}), ran {', '.join(labels) or 'no MBIT'}")
        if complete:
            self.active = False
        return BoardEvent("maintenance_verdict", tick, tick * self.period,
                          {"verdict": verdict, "mbits": ",".join(labels), "detail": detail})
