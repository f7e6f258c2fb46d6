"""The rig's high-voltage amplifier: command validation, the demand it holds, the slew between ticks, the watchdog."""

from __future__ import annotations

from board_config import MfcLimits
from drivers.link import ActuatorCommand

#: largest board current (A) a command may carry
BOARD_CURRENT_MAX = 10.0


class Amplifier:
    """Takes the board's commands: a command is valid when finite, inside Table 1's per-channel voltage range and
    with a board current in [0, 10) A; an invalid one is refused (the last valid demand stays, ``refused_flag``
    is set until the next valid one). Between two ticks the output slews linearly from the last output to the
    demand (a first-order hold). No valid command for ``watchdog`` seconds → the demand drops to 0 V.

    The channel voltages are plain float attributes (V): the demand in force ``v_ch1``/``v_ch2`` and the output at
    the end of the last interval ``last_ch1``/``last_ch2`` (the start of the next slew); the rig reads them every
    tick."""

    def __init__(self, limits: MfcLimits, watchdog: float) -> None:
        self.limits = limits
        self.watchdog = watchdog
        self._lo = limits.voltage_min
        self._hi = limits.voltage_max
        self.v_ch1 = 0.0  # demand in force (V)
        self.v_ch2 = 0.0
        self.last_ch1 = 0.0  # output at the end of the last interval (V)
        self.last_ch2 = 0.0
        self.board_current = 0.0  # A, the board's draw from its cell as last commanded
        self.refused_commands = 0
        self.watchdog_trips = 0
        self.refused_flag = False
        self._last_command_t = 0.0
        self._watchdog_open = False

    def apply(self, command: ActuatorCommand, t: float) -> None:
        """Take ``command`` at rig time ``t`` (s), or refuse it."""
        v1, v2, i = command.v_ch1, command.v_ch2, command.board_current
        lo, hi = self._lo, self._hi
        if not (lo <= v1 <= hi and lo <= v2 <= hi and 0.0 <= i < BOARD_CURRENT_MAX):  # NaN fails every comparison
            self.refused_commands += 1
            self.refused_flag = True
            return
        self.refused_flag = False
        self.v_ch1 = float(v1)
        self.v_ch2 = float(v2)
        self.board_current = float(i)
        self._last_command_t = t
        self._watchdog_open = False

    def check_watchdog(self, t: float) -> None:
        """Drop the demand to 0 V if no valid command came for longer than ``watchdog`` before ``t``."""
        if t - self._last_command_t > self.watchdog + 1e-12 and not self._watchdog_open:
            self._watchdog_open = True
            self.watchdog_trips += 1
            self.v_ch1 = 0.0
            self.v_ch2 = 0.0
