"""The board: composition of the pieces, one call per 100 Hz tick — ``tick(sample, k) -> command + events``.

Per tick ``k`` (board time ``k / rate``), given the rig sample the link returned (``None`` if the exchange failed):

1. **Percepts** (pure): plausibility of the sample (``sample_check``: NaN/Inf, out of range, rig fault flags; a
   frozen sequence number for ``[tick] stale_ticks``, a counter that keeps stepping back: ``sample_order``) → sensor
   fault; the rig's "limit refused" flag or a demand the output guard had to clamp → limit violation; the wake
   comparator (|v_patch| ≥ ``[wake] patch_voltage`` or |z̈0| ≥ ``[wake] base_acceleration``); HV presence; the
   scheduler's overrun flag; an operator re-arm request.
2. **Power manager** (``power_manager.power_step``): brown-out and "energy to wake".
3. **Regimes** (``regimes.step``): the transition table decides the regime.
4. **Regime work**: entering SENSING opens a usage episode (``usage.UsageEpisode``), fed every SENSING tick and
   summarised on exit or every ``[sensing] max_episode``; MAINTENANCE runs the MBIT sequence
   (``maintenance.MaintenanceSequencer``: condition monitor + nominal model over the planned sequence); leaving
   either closes it.
5. **Output guard**: a non-zero demand only in MAINTENANCE; every channel voltage checked against Table 1
   (``board_config.load_mfc_limits()``) — never leaves the range whatever the sequencer, config or link say; a
   demand that had to be clamped is an incident and a limit violation (→ SAFE next tick).
6. **Command**: the channel voltages and the board's current draw for its regime (the rig's battery sees it).

Events (``events.BoardEvent``) go to the usage log; the board itself does no I/O and reads no clock. Deterministic:
the same samples give the same commands and events.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import NamedTuple

import numpy as np

from board_config import (
    MbitDefinition,
    MfcLimits,
    MonitorSettings,
    ParameterSet,
    load_mbit_definitions,
    load_mfc_limits,
    load_monitor_settings,
)
from board_config.board import BoardConfig, load_board_config
from board_config.errors import InputError
from drivers.link import FLAG_LIMIT_REFUSED, ActuatorCommand, RigSample
from drivers.quiet_span import QuietSpan
from firmware_sim.events import BoardEvent
from firmware_sim.maintenance import MaintenanceSequencer
from firmware_sim.power_manager import PowerBudget, PowerLedger, PowerState, PowerStatus, power_step
from firmware_sim.regimes import (
    Regime,
    RegimeState,
    RegimeTimers,
    TickInputs,
    Trigger,
    quiet_awake,
    quiet_standby,
)
from firmware_sim.regimes import step as regime_step
from firmware_sim.rig_clock import CLOCK_WINDOW, clocks_agree, mismatch_reason, quiet_clock_checks
from firmware_sim.sample_check import SampleLimits, check_sample, plausible_samples
from firmware_sim.sample_order import StepsBack, clock_backwards_reason, seq_backwards_reason, steps_back
from firmware_sim.usage import UsageEpisode
from plant import PlantModel

_QUIET_OK = TickInputs()
_QUIET_LOW = TickInputs(energy_ok=False)
_INF = math.inf


class TickResult(NamedTuple):
    command: ActuatorCommand
    events: list[BoardEvent]
    regime: Regime


class Board:
    """The SHM board firmware mock.

    Parameters
    ----------
    config:
        Board configuration (default: ``board_config/board.toml``).
    nominal:
        The nominal model parameter set for the condition monitor (name, path or ParameterSet; default ``table2``).
    limits, monitor, mbits:
        Table 1 limits, Table 3 monitor settings, MBIT definitions (defaults: the shipped ``board_config`` files).
    """

    def __init__(self, config: BoardConfig | None = None, *, nominal: str | ParameterSet = "table2",
                 limits: MfcLimits | None = None, monitor: MonitorSettings | None = None,
                 mbits: Mapping[str, MbitDefinition] | None = None, nominal_model: PlantModel | None = None) -> None:
        self.cfg = cfg = config if config is not None else load_board_config()
        self.limits = limits if limits is not None else load_mfc_limits()
        monitor = monitor if monitor is not None else load_monitor_settings()
        if abs(monitor.f_mon - cfg.tick_rate) > 1e-9:
            raise InputError(f"the condition monitor runs at f_mon = {monitor.f_mon:g} Hz (monitor.toml) but the "
                             f"board ticks at {cfg.tick_rate:g} Hz (board.toml [tick] rate): they must agree")
        self.timers = RegimeTimers.from_config(cfg)
        self.budget = PowerBudget.from_config(cfg)
        self.period = cfg.tick_period
        model = nominal_model if nominal_model is not None else PlantModel(nominal, terminal="amplifier")
        model.kernels()  # compiled (or loaded from the cache) now, not at the first maintenance visit
        self.maintenance = MaintenanceSequencer(
            cfg.maintenance_sequence, mbits if mbits is not None else load_mbit_definitions(), self.limits, monitor,
            model, cfg.ticks(cfg.maintenance_settle), self.period)
        self.state = RegimeState()
        self.power = PowerState()
        self.ledger = PowerLedger(self.budget)
        self._currents = {r: self.budget.current(r) for r in Regime}
        self._wake_v = cfg.wake_patch_voltage
        self._sample_limits = SampleLimits.from_config(cfg)
        self._wake_acc = cfg.wake_base_acceleration
        self._v_lo, self._v_hi = self.limits.voltage_min, self.limits.voltage_max
        self.episode: UsageEpisode | None = None
        self._episode_ticks = max(1, cfg.ticks(cfg.sensing_max_episode))
        self._telemetry_ticks = max(1, cfg.ticks(cfg.log_telemetry_period))
        self._rearm = False
        self._limit_pending = ""
        self._prev_seq = -1
        self._prev_t = -math.inf
        self._back = StepsBack()  # recent steps back of the rig's counter and clock
        self._stale = 0
        self._fault_reason = ""
        self._fault_key = ""  # the persisting sensor condition ('' = none)
        self._fault_since = 0
        self._fault_ticks = 0
        self._link_error = ""  # the first error of the current run of failed exchanges ('' = link healthy)
        self._link_failures = 0
        self._link_since = 0
        self._clock_ref: tuple[int, float] | None = None  # (tick, rig time s) the clock check measures from
        self.clock_mismatch = ""  # why the rig's clock and the board's disagree ('' = they agree)
        self.visit_verdict = ""  # verdict of the last finished visit while HV stays present ('' = none)
        self.incidents = 0
        self.last_sample: RigSample | None = None
        self.demand = (0.0, 0.0)
        self.ticks = 0
        self._v_batt = math.nan

    def set_realtime_rig(self, realtime: bool) -> None:
        """A real-time rig answers with its latest snapshot, taken before the command it answers acts (one tick of
        link delay); a lock-step or in-process rig answers after it. With ``realtime`` the monitor estimates which
        from the visit's samples (0 or 1 tick); without, it assumes 0 (the default)."""
        self.maintenance.set_link_lags((0, 1) if realtime else (0,))

    # --- operator -----------------------------------------------------------------------------------
    def request_rearm(self) -> None:
        """Operator re-arm: taken into account at the next tick (refused, and logged, while a cause persists)."""
        self._rearm = True

    @property
    def regime(self) -> Regime:
        return self.state.regime

    @property
    def monitor_count(self) -> int:
        return self.maintenance.monitor_count

    # --- the tick -----------------------------------------------------------------------------------
    def tick(self, sample: RigSample | None, k: int, *, overrun: bool = False, link_error: str = "") -> TickResult:
        """Process tick ``k``: the sample the link returned (``None``: the exchange failed, ``link_error`` says why),
        whether the previous tick overran its deadline; return the command for the next interval and the events."""
        events: list[BoardEvent] = []
        self.ticks += 1

        # 1. percepts
        if sample is not None:
            sensor_fault, wake, v_meas = self._perceive(sample, k, events)
            hv = sample.hv_present
        else:
            self._exchange_failed(k, link_error, events)
            sensor_fault = wake = hv = False
            v_meas = math.nan  # no battery voltage this tick
        limit = bool(self._limit_pending)
        if limit:
            events.append(self._incident(k, "limit_violation", self._limit_pending))
            self._limit_pending = ""

        # 2. power manager (the battery voltage of a faulty sample is not trusted)
        old = self.state.regime
        pstat = self._power_step(v_meas, old, k, events)

        # 3. regimes
        ok = sample is not None
        if ok and not (sensor_fault or limit or overrun or wake or hv or pstat.brownout or self._rearm):
            inputs = _QUIET_OK if pstat.energy_ok else _QUIET_LOW  # the common case, without building a tuple
        else:
            inputs = TickInputs(ok, sensor_fault, limit, overrun, wake, hv, pstat.energy_ok, pstat.brownout,
                                self._rearm)
        regime = self._regime_step(inputs, old, k, events)

        # 4. regime work, 5. output guard
        v1, v2 = self._regime_work(regime, None if sensor_fault else sample, k, events)
        self.demand = (v1, v2)

        # 6. telemetry and command
        if k % self._telemetry_ticks == 0:
            events.append(self._telemetry(k, regime))
        return TickResult(ActuatorCommand(k & 0xFFFFFFFF, v1, v2, self._currents[regime]), events, regime)

    def _perceive(self, sample: RigSample, k: int, events: list[BoardEvent]) -> tuple[bool, bool, float]:
        """Stage 1 for a sample the link returned: (sensor fault, wake comparator, battery voltage in V or NaN when
        the sample is not trusted). Also the rig's "limit refused" flag (a pending limit violation), the end of a
        run of failed exchanges and the check of the rig's clock."""
        reason = self._sample_fault(sample, k, events)
        # a persisting condition is one incident when it starts (and one when it ends, with its count), not
        # one per tick: the reason's first two words name the condition, the rest carries this tick's values
        if reason:
            key = " ".join(reason.split()[:2])
            if key != self._fault_key:
                self._close_fault(k, events)
                events.append(self._incident(k, "sensor_fault", reason))
                self._fault_key, self._fault_since, self._fault_ticks = key, k, 0
            self._fault_ticks += 1
            wake = False
            v_meas = math.nan
        else:
            if self._fault_key:
                self._close_fault(k, events)
            v_meas = self._v_batt = sample.v_battery
            wake = abs(sample.z0dd) >= self._wake_acc or abs(sample.v_patch) >= self._wake_v
        self._fault_reason = reason
        if sample.flags & FLAG_LIMIT_REFUSED and not self._limit_pending:
            self._limit_pending = "the rig refused a command (limit refused flag)"
        if self._link_error:
            events.append(self._incident(
                k, "link_restored", f"link answered again after {self._link_failures} failed exchange(s) "
                                    f"({(k - self._link_since) * self.period:.2f} s); first error: {self._link_error}"))
            self._link_error = ""
        ref = self._clock_ref  # the common case (inside the window, clock sane) without a call
        if ref is None or not (ref[1] <= sample.t < _INF) or (k - ref[0]) * self.period >= CLOCK_WINDOW:
            self._check_clock(k, sample.t, events)
        self.last_sample = sample
        return bool(reason), wake, v_meas

    def _sample_fault(self, sample: RigSample, k: int, events: list[BoardEvent]) -> str:
        """Why this sample cannot be trusted ('' if it can): :func:`check_sample`, a sequence number frozen for
        ``[tick] stale_ticks``, or a counter or clock that keeps stepping back (:mod:`firmware_sim.sample_order`)."""
        reason = check_sample(sample, self._sample_limits)
        prev_seq, prev_t = self._prev_seq, self._prev_t
        if sample.seq == prev_seq:
            self._stale += 1
            stale_ticks = self.cfg.tick_stale_ticks
            if self._stale >= stale_ticks and not reason:
                reason = f"rig_seq frozen at {sample.seq} for {stale_ticks} ticks or more (stale sensor path)"
        else:
            self._stale = 0
        self._prev_seq, self._prev_t = sample.seq, sample.t
        if sample.seq < prev_seq or sample.t < prev_t or self._back.any:  # a step back
            reason = self._check_order(k, prev_seq, prev_t, sample, reason, events)
        return reason

    def _exchange_failed(self, k: int, link_error: str, events: list[BoardEvent]) -> None:
        """Stage 1 without a sample: the first failed exchange of a run is an incident; the rest are counted."""
        if not self._link_error:
            self._link_error = link_error or "exchange failed"
            events.append(self._incident(k, "link_error", self._link_error))
            self._link_failures = 0
            self._link_since = k
        self._link_failures += 1

    def _power_step(self, v_meas: float, regime: Regime, k: int, events: list[BoardEvent]) -> PowerStatus:
        """Stage 2: the power manager on this tick's battery voltage (NaN: not trusted) and the charge ledger."""
        self.power, pstat, pev = power_step(self.power, v_meas, regime, k, self.budget)
        self.ledger.add(regime, v_meas)
        if pev:
            events.extend(pev)
            self.incidents += len(pev)
        return pstat

    def _regime_step(self, inputs: TickInputs, old: Regime, k: int, events: list[BoardEvent]) -> Regime:
        """Stage 3: the transition table (:func:`firmware_sim.regimes.step`) and the work of a regime change."""
        self._rearm = False
        self.state, out, rev = regime_step(self.state, inputs, k, self.timers)
        if self.visit_verdict and self.state.hv_off_run >= self.timers.hv_debounce:
            self.visit_verdict = ""  # HV removed: the next application of HV starts a new visit
        for ev in rev:
            if ev.kind == "regime_change":
                data = dict(ev.data)
                data["v_battery_V"] = self._v_batt
                ev = BoardEvent(ev.kind, ev.tick, ev.time, data)
            else:
                self.incidents += 1
            events.append(ev)
        if out.changed:
            events.extend(self._on_change(old, out.regime, out.trigger, k))
        return out.regime

    def _regime_work(self, regime: Regime, trusted: RigSample | None, k: int, events: list[BoardEvent]
                     ) -> tuple[float, float]:
        """Stages 4 and 5: SENSING feeds the usage episode, MAINTENANCE steps the MBIT sequence, whose demand the
        output guard checks against Table 1; the channel voltages (V) to send. ``trusted``: the sample, or None when
        there is none or it is not trusted."""
        if regime is Regime.SENSING:
            if trusted is not None:
                ep = self.episode
                if ep is None:  # pragma: no cover - opened on entry
                    ep = self.episode = self._new_episode(k * self.period)
                ep.add(k * self.period, trusted.z3, trusted.z0dd)
                if ep.samples >= self._episode_ticks:
                    events.append(self._summary(k, "max_episode"))
                    self.episode = self._new_episode(k * self.period)
        elif regime is Regime.MAINTENANCE and self.maintenance.active:
            (v1, v2), mev = self.maintenance.step(k, trusted.z3 if trusted is not None else math.nan)
            events.extend(mev)
            for ev in mev:
                if ev.kind == "maintenance_verdict":
                    self.visit_verdict = str(ev.data["verdict"])
            # 5. output guard: Table 1 always (outside MAINTENANCE the demand is 0 V by construction)
            lo, hi = self._v_lo, self._v_hi
            if lo <= v1 <= hi and lo <= v2 <= hi:
                return v1, v2
            self._limit_pending = f"demand ({v1!r}, {v2!r}) V outside Table 1 [{lo:g}, {hi:g}] V: zero sent"
        return 0.0, 0.0

    def _telemetry(self, k: int, regime: Regime) -> BoardEvent:
        return BoardEvent("telemetry", k, k * self.period, {
            "regime": regime.value, "v_battery_V": self._v_batt, "monitor_count": self.maintenance.monitor_count,
            "charge_used_C": self.ledger.charge_used, "incidents_total": self.incidents})

    # --- quiet spans: settled stand-by ticks at once ---------------------------------------------------------
    def can_take_quiet(self) -> bool:
        """Whether a quiet tick — a plausible, fresh sample without a flag, the battery above the brown-out voltage,
        HV present in maintenance and absent otherwise; in stand-by also below both wake thresholds — changes nothing
        but counters (stand-by: :func:`firmware_sim.regimes.quiet_standby`; sensing, and maintenance after the visit's
        verdict: :func:`firmware_sim.regimes.quiet_awake`; the usage episode in sensing): one of those regimes,
        nothing pending. The precondition of :meth:`take_quiet`."""
        regime = self.state.regime
        return (((regime is Regime.STANDBY_HARVEST and self.episode is None)
                 or (regime is Regime.SENSING and self.episode is not None)
                 or (regime is Regime.MAINTENANCE and self.episode is None and bool(self.visit_verdict)))
                and not self._rearm and not self._limit_pending and not self._fault_key and not self._link_error
                and not self.maintenance.active and self._clock_ref is not None and not self.power.brownout)

    def quiet_command_current(self) -> float:
        """The board current (A) the commands of a quiet stretch carry (its regime's; zero demand)."""
        return self._currents[self.state.regime]

    def take_quiet(self, k: int, span: QuietSpan) -> tuple[int, ActuatorCommand | None]:
        """Ticks ``k, k + 1, ...`` with the samples of ``span`` (:mod:`drivers.quiet_span`), as many as are quiet:
        the leading run of ticks :meth:`tick` would process without an event, a regime change or a telemetry record
        (it stops before the next telemetry tick, before a check of the rig's clock that would report a mismatch,
        and in sensing before the tick that ends or slices the usage episode). Returns how many ticks it took (0:
        none; the caller ticks one by one) and the command after the last. Bit-identical to that many calls of
        :meth:`tick`; call only when :meth:`can_take_quiet`."""
        regime = self.state.regime
        n = min(span.n, (-k) % self._telemetry_ticks)  # ticks before the next telemetry tick (0: tick k is one)
        ep = self.episode
        if regime is Regime.SENSING and ep is not None:  # before the tick that slices the episode (max_episode)
            n = min(n, self._episode_ticks - 1 - ep.samples)
        ref_k, ref_t = self._clock_ref  # type: ignore[misc]  # can_take_quiet: set
        if (n < 1 or span.seq0 == self._prev_seq or not ref_t <= float(span.t[0]) or self._back.any
                or span.hv_present != (regime is Regime.MAINTENANCE)):
            return 0, None
        z3, zdd, vb, t = span.z3[:n], span.z0dd[:n], span.v_battery[:n], span.t[:n]
        avp, azdd = np.abs(span.v_patch[:n]), np.abs(zdd)
        good = plausible_samples(z3, avp, azdd, vb, t, self._sample_limits) & (vb >= self.budget.brownout)
        wake = (azdd >= self._wake_acc) | (avp >= self._wake_v)
        quiet = good & ~wake if regime is Regime.STANDBY_HARVEST else good
        m = n if bool(quiet.all()) else int(np.argmin(quiet))
        period = self.period
        m, checks = quiet_clock_checks(k, m, (ref_k, ref_t), t, period, bool(self.clock_mismatch))
        if m < 1:
            return 0, None
        if regime is Regime.STANDBY_HARVEST:
            state = quiet_standby(self.state, self.timers, m)
            if state is None:
                return 0, None
        else:  # sensing up to the tick where quiet fires (the usage episode takes every sample); maintenance idle
            state, m = quiet_awake(self.state, self.timers, wake[:m].tolist())
            if m < 1:
                return 0, None
            if ep is not None:
                add = ep.add
                for kk, z, a in zip(range(k, k + m), z3[:m].tolist(), zdd[:m].tolist(), strict=True):
                    add(kk * period, z, a)
        for tick_c, t_c in checks:
            if tick_c < k + m:
                self._clock_ref = (tick_c, t_c)
        self.state = state
        if self.visit_verdict and state.hv_off_run >= self.timers.hv_debounce:
            self.visit_verdict = ""  # HV removed for hv_debounce (no event: see tick)
        if self.power.below_run:
            self.power = self.power._replace(below_run=0)
        last = k + m - 1
        self.ticks += m
        self._prev_seq, self._prev_t = (span.seq0 + m - 1) & 0xFFFFFFFF, float(t[m - 1])
        self._stale = 0
        self._fault_reason = ""
        self._v_batt = float(vb[m - 1])
        self.last_sample = span.sample(m - 1)
        self.ledger.add_many(regime, vb[:m])
        self.demand = (0.0, 0.0)
        return m, ActuatorCommand(last & 0xFFFFFFFF, 0.0, 0.0, self._currents[regime])

    # --- helpers ------------------------------------------------------------------------------------
    def _close_fault(self, k: int, events: list[BoardEvent]) -> None:
        """The persisting sensor condition (if any) has ended: one record with how long it lasted."""
        if self._fault_key:
            events.append(self._incident(k, "sensor_fault_cleared", (
                f"{self._fault_reason or self._fault_key} — ended after {self._fault_ticks} tick(s) "
                f"({(k - self._fault_since) * self.period:.2f} s)")))
            self._fault_key = ""
            self._fault_ticks = 0

    def _check_order(self, k: int, prev_seq: int, prev_t: float, sample: RigSample, reason: str,
                     events: list[BoardEvent]) -> str:
        """A rig whose counter or clock keeps stepping back (:mod:`firmware_sim.sample_order`): the clock incident
        (once per run) and the sensor-fault reason (``reason`` if there is one already)."""
        self._back = steps_back(self._back, prev_seq, sample.seq, prev_t, sample.t, k * self.period)
        clock = clock_backwards_reason(self._back, prev_t, sample.t)
        if clock and not self.clock_mismatch:
            self.clock_mismatch = clock
            events.append(self._incident(k, "clock_mismatch", clock))
        return reason or seq_backwards_reason(self._back, prev_seq, sample.seq)

    def _check_clock(self, k: int, t_rig: float, events: list[BoardEvent]) -> None:
        """Compare the rig's clock (sample time) with the board's (tick count) every ``CLOCK_WINDOW`` s
        (:mod:`firmware_sim.rig_clock`); a mismatch is said once per run."""
        ref = self._clock_ref
        if ref is None or not math.isfinite(t_rig) or t_rig < ref[1]:  # first sample, or the rig restarted
            self._clock_ref = (k, t_rig)
            return
        board_dt = (k - ref[0]) * self.period
        if board_dt < CLOCK_WINDOW:
            return
        rig_dt = t_rig - ref[1]
        self._clock_ref = (k, t_rig)
        if not clocks_agree(board_dt, rig_dt) and not self.clock_mismatch:
            self.clock_mismatch = mismatch_reason(board_dt, rig_dt)
            events.append(self._incident(k, "clock_mismatch", self.clock_mismatch))

    def _incident(self, k: int, kind: str, detail: str) -> BoardEvent:
        self.incidents += 1
        return BoardEvent("incident", k, k * self.period,
                          {"incident": kind, "regime": self.state.regime.value, "detail": detail})

    def _new_episode(self, now: float) -> UsageEpisode:
        c = self.cfg
        return UsageEpisode(now, self.period, c.sensing_exceedance_levels, c.sensing_rainflow_gate,
                            c.sensing_rainflow_bin_width)

    def _summary(self, k: int, reason: str) -> BoardEvent:
        assert self.episode is not None
        summ = self.episode.summary(k * self.period, reason)
        return BoardEvent("usage_summary", k, k * self.period, summ.as_record())

    def _on_change(self, old: Regime, new: Regime, trigger: Trigger | None, k: int) -> list[BoardEvent]:
        events: list[BoardEvent] = []
        reason = trigger.value if trigger is not None else "?"
        if old is Regime.SENSING and self.episode is not None:
            events.append(self._summary(k, reason))
            self.episode = None
        if old is Regime.MAINTENANCE:
            events.extend(self.maintenance.abort(k, reason))
            self.maintenance.finish()
        if new is Regime.SENSING:
            self.episode = self._new_episode(k * self.period)
        elif new is Regime.MAINTENANCE:
            if self.visit_verdict:  # back after a SAFE while HV stayed present: the finished visit stands
                events.append(self._incident(k, "visit_kept", (
                    f"MAINTENANCE re-entered with HV still present after a finished visit: its verdict "
                    f"{self.visit_verdict} stands; the MBITs run again only when HV is removed and applied anew")))
            else:
                events.extend(self.maintenance.start(k))
        self.incidents += sum(1 for e in events if e.kind == "incident")
        return events

    def close(self, k: int) -> list[BoardEvent]:
        """End of the run at tick ``k``: summarise an open usage episode, log an unfinished visit."""
        events: list[BoardEvent] = []
        if self.episode is not None:
            events.append(self._summary(k, "end"))
            self.episode = None
        if self.maintenance.active:
            events.extend(self.maintenance.abort(k, "end of run"))
        return events
