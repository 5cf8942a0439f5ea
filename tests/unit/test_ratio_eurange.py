"""MAG_1.Ratio has an EURange (issue 24): the MAG seed gives the real ratio's range,
"0.00001 to 9.99999" in magnitude, signed (the sign selects the direction), so the span
in normal operation is [-9.99999, 9.99999]; the OPC UA model then types it as an
AnalogItemType with that EURange, as every other analog operand with a range."""

from __future__ import annotations

from motion_server import config
from motion_server.tagmap import build_tagmap
from motion_server.tagmap.nodeset import Ns0, variable_type

SEED_MAX = 9.99999  # MAG: Ratio 0.00001 to 9.99999


def test_mag_ratio_has_the_seeds_range_as_its_eurange() -> None:
    tagmap = build_tagmap(config.load())
    ratio = tagmap.tag("MAG_1.Ratio")
    assert ratio.eu_range == (-SEED_MAX, SEED_MAX)
    assert variable_type(ratio) == Ns0.ANALOG_ITEM_TYPE
