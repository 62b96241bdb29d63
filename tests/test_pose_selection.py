"""Pose selection: the chosen poses beat as many random ones on the criterion they were chosen by."""

import pytest
from robots import arm6r

import robocal as rc


@pytest.mark.parametrize("criterion", ["I", "D"])
def test_selected_poses_beat_random_ones_on_their_criterion(criterion):
    sel = rc.select_poses(arm6r(), 30, criterion=criterion, rng=1)
    assert sel.criterion == criterion and sel.q.shape == (30, 6) and len(set(sel.indices)) == 30
    if criterion == "I":
        # the average prediction variance over the workspace, what the held-out error depends on
        assert sel.prediction_selected < 0.8 * sel.prediction_random
    else:
        assert sel.log_det_selected > sel.log_det_random
