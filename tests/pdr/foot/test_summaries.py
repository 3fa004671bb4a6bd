"""Step summaries (pdr-foot-steps/1): the stride flag round-trips through the payload and the stored form, and a
blob stored before the flag reads as all strides."""

import numpy as np

from pdr import state_codec
from pdr.foot import summaries_codec
from pdr.foot.navigate import navigate
from pdr.foot.summaries import steps_from_json, steps_to_json
from tests.pdr.foot.test_online import gait_recording


def test_stride_flags_round_trip_and_default_to_strides():
    _, track = navigate(gait_recording(), "stepwise")
    flags = track.step_strides
    assert False in flags and True in flags
    batch = steps_from_json(steps_to_json(list(track.steps), "left_foot", "b"))
    assert batch.strides == flags
    again = summaries_codec.loads(summaries_codec.dumps(batch))
    assert again.strides == flags and [s.t_s for s in again.steps] == [s.t_s for s in batch.steps]
    plain = steps_to_json(list(track.steps), "left_foot", "b")
    for step in plain["steps"]:
        del step["stride"]
    assert steps_from_json(plain).strides == (True,) * len(track.steps)
    # A version-1 blob (stored before the flag) reads as strides throughout.
    state = state_codec.loads(summaries_codec.dumps(batch))
    del state["stride"]
    state["version"] = 1
    old = summaries_codec.loads(state_codec.dumps(state))
    assert old.strides == (True,) * len(track.steps)
    np.testing.assert_array_equal([s.dp for s in old.steps], [s.dp for s in batch.steps])
