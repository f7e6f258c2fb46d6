"""The simulated rig: a truth plant (nominal physics + injected effects, deviations, noise, faults) served
in-process or over serial / Modbus so the firmware cannot tell it from hardware."""
