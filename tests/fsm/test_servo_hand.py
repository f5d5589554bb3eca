"""The task cycle with the generic servo hand (``fsm.run --hand servo``, issue 24): the hand of
the results measured before the Utah/MIT hand became the default stays a named option, and it
still delivers clutter3, judged physically. (The default hand's episodes are every other
end-to-end test.)"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fsm.run import main


@pytest.mark.e2e
def test_clutter3_is_delivered_by_the_servo_hand(tmp_path: Path) -> None:
    code = main(["--scene", "clutter3", "--hand", "servo", "--no-record", "--out", str(tmp_path)])
    s = json.loads((tmp_path / "summary.json").read_text())
    assert code == 0 and s["success"], s["failure_detail"]
    assert s["options"]["hand"] == "servo"
    (cycle,) = s["cycles"]
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0
    assert j["lift_clearance_m"] >= 0.05 and not j["finger_contact"]
    assert min(cycle["grip_forces"]) > 0.5 * min(cycle["grip_target"])
