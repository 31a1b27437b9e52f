"""A touch on the back of a thin pad (`fruitcli.electrostatics.back_touch`), solved on a
coarse pad (mm, fF)."""

from __future__ import annotations

import numpy as np
import pytest

from fruitcli.electrostatics.back_touch import Pad, pad_spec

PAD = Pad(8.0, 8.0, 3.5, 1.0, 0.4, 0.1, 2.8)
"""The crossing 1 mm under the front of a 3.5 mm pad: 0.15 mm of silicone over the
upper yarn, 1.65 mm under the lower one."""


def test_the_back_cell_is_the_mirrored_pad():
    """From the back the crossing lies thickness - depth under the touched face, the
    silicone ends at the pad's other face with air beyond, the pitches exchanged."""
    pad = Pad(10.0, 9.0, 3.5, 1.0, 0.4, 0.1, 2.8)
    front, back = pad_spec(pad, "front"), pad_spec(pad, "back")
    assert front.cover_mm == 1.0 and back.cover_mm == 2.5
    assert (front.pitch_x_mm, front.pitch_y_mm) == (10.0, 9.0)
    assert (back.pitch_x_mm, back.pitch_y_mm) == (9.0, 10.0)
    assert front.bottom_z_mm == pytest.approx(-3.5) and back.bottom_z_mm == pytest.approx(-3.5)
    assert front.back_air_mm > 0 and back.back_air_mm > 0


@pytest.mark.parametrize("depth", [0.85, 2.65, 3.0])
def test_a_crossing_that_does_not_fit_the_pad_is_refused(depth):
    """Two yarn diameters and the insulation (1.7 mm) must lie inside the 3.5 mm pad."""
    pad = Pad(8.0, 8.0, 3.5, depth, 0.4, 0.1, 2.8)
    with pytest.raises(ValueError, match=r"does not fit a 3.5 mm pad.*\(0.85, 2.65\) mm"):
        pad_spec(pad, "back")


def test_a_finger_behind_the_pad_drops_less_than_in_front():
    """The finger touching the back face, 2.5 mm from the crossing, takes less field from
    the crossing than on the front face, 1 mm from it; both drops are finite and
    negative (a grounded finger), and the pad's C0 is the same seen from either side
    (one pad meshed twice, mirrored) within the discretization."""
    from fruitcli.electrostatics.back_touch import contact_drops_ff

    d = contact_drops_ff(PAD, "finger", time_limit_s=60.0)
    front, back = d["front"], d["back"]
    assert np.isfinite([front["dc"], back["dc"]]).all()
    assert front["dc"] < 0 and back["dc"] < 0
    assert back["dc"] > 0.8 * front["dc"]  # smaller in size: at least 20 % less
    assert back["c0"] == pytest.approx(front["c0"], rel=0.06)


def test_the_pad_bent_shifts_a_crossing_over_and_under_its_neutral_plane_oppositely():
    """Bent as the paper's pad about the plane 1.5 mm under the front, the crossing 1 mm
    deep (stretched side) and 2.5 mm deep (compressed side) of the 3.5 mm pad shift C in
    opposite directions along each yarn; the larger shift is fitted to 10 counts."""
    from fruitcli.electrostatics.back_touch import bend_counts_per_ff

    over_cpf, over = bend_counts_per_ff(PAD, time_limit_s=60.0)
    under_cpf, under = bend_counts_per_ff(Pad(8.0, 8.0, 3.5, 2.5, 0.4, 0.1, 2.8), 60.0)
    for a in "xy":
        assert over[a] * under[a] < 0, (over, under)
    for cpf, shift in ((over_cpf, over), (under_cpf, under)):
        assert cpf * max(abs(shift["x"]), abs(shift["y"])) == pytest.approx(10.0)
