"""QGC WPL 110 waypoint files (MAVProxy `wp save` / `wp load`, Mission Planner, QGroundControl export)."""

import math

import pytest

from c4d_common.geodesy import GeoOrigin
from c4d_common.plan import PlanError
from c4d_common.plan_files import load_plan, plan_from_wpl_text
from c4d_common.plan_validation import validate

HOME = GeoOrigin(43.5629, 1.4815, 146.0)
# as MAVProxy saves it: row 0 = home (absolute altitude, frame 0), then relative-altitude rows, no take-off
WPL = """QGC WPL 110
0\t1\t0\t16\t0\t0\t0\t0\t43.5629\t1.4815\t146.0\t1
1\t0\t3\t16\t0\t0\t0\t0\t43.56295\t1.48155\t6.0\t1
2\t0\t0\t16\t0\t0\t0\t0\t43.56300\t1.48155\t152.0\t1
3\t0\t2\t20\t0\t0\t0\t0\t0\t0\t0\t1
"""


def test_a_wpl_file_with_its_home_row_and_no_take_off_is_a_valid_plan(tmp_path):
    """Issue 14: such a file was refused (item 0 = the home row as a waypoint, `before any take-off`)."""
    plan = plan_from_wpl_text(WPL)
    assert [i.type for i in plan.items] == ["waypoint", "waypoint", "rtl"]  # the home row is not an item
    assert plan.items[0].z == 6.0 and plan.items[1].z == pytest.approx(6.0)  # AMSL row: above the home row
    assert math.isclose(plan.items[0].x, 43.56295) and math.isclose(plan.items[0].y, 1.48155)
    result = validate(plan, HOME)
    assert result.ok, result.errors
    path = tmp_path / "mission.waypoints"
    path.write_text(WPL.replace("\t", " "))  # any whitespace, any suffix: the header decides
    assert load_plan(path) == plan


@pytest.mark.parametrize("text,message", [
    ("QGC WPL 100\n", "not a waypoint file"),
    (WPL.replace("2\t0\t0\t16", "5\t0\t0\t16"), "line 4: row 5 where row 2 was expected"),
    (WPL.replace("\t1\n3", "\n3"), "line 4: 12 values needed, got 11"),
    (WPL.replace("3\t0\t2\t20", "3\t0\t2\t999"), "item 3: unsupported MAVLink command 999"),
    (WPL.replace("0\t1\t0\t16", "0\t1\t3\t16"), "item 2: AMSL frame 0 needs a home altitude"),
])
def test_malformed_wpl_files_name_the_line_or_item(text, message):
    with pytest.raises(PlanError, match=message):
        plan_from_wpl_text(text)
