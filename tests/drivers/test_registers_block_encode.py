"""The input block encoded in one ``struct.pack`` (what every sample request of the stub does, issue 29 point 2) gives
the same registers as the register-by-register reference through the map, for any sample: saturation, rounding,
non-finite values, counters that wrap."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.link import RigSample
from drivers.modbus_registers import INPUT_COUNT, encode_input_block, encode_input_block_by_register

EDGES = [0.0, -0.0, 1e-6, -1e-6, 0.327675, 0.3276749, -0.32768, 65.535, 65.5355, 3276.75, -3276.85, 1e40, -1e40,
         3.3e38, math.inf, -math.inf, math.nan]
values = st.one_of(st.sampled_from(EDGES), st.floats(allow_nan=True, allow_infinity=True, width=64))


@settings(max_examples=400, deadline=None)
@given(seq=st.integers(0, 2**40), t=values, z3=values, v_patch=values, z0dd=values, v_battery=values,
       hv=st.booleans(), flags=st.integers(0, 255), cmd_seq=st.integers(0, 2**34), refused=st.integers(0, 2**20))
def test_the_packed_block_equals_the_map_reference(seq, t, z3, v_patch, z0dd, v_battery, hv, flags, cmd_seq,
                                                    refused):
    s = RigSample(seq=seq, t=t, z3=z3, v_patch=v_patch, z0dd=z0dd, v_battery=v_battery, hv_present=hv, flags=flags)
    fast = encode_input_block(s, cmd_seq, refused)
    assert len(fast) == INPUT_COUNT and fast == encode_input_block_by_register(s, cmd_seq, refused)
