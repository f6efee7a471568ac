"""Link noise on the robot twin: compiled programs stay exactly on the reference.

Nothing of the serve loop is given up on: a lost or damaged byte costs a retry, never a
neighbour's state (protocol/link.md §4.2). Figures for other
noise levels and seeds (the old protocol): docs/compile.md "Link noise"; the serve loop under
noise: docs/link-redesign.md §5.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import TracedBuild, traced_controller

from bstool.controllers import load_controller
from bstool.wire import link
from hil_mock.robot import RobotTwin, load_build

TRANSITIONS = 30
NOISE = 0.002
SEED = 7


@pytest.mark.parametrize("model", ["ca2ddiff", "nnsin"])
def test_noisy_links_keep_the_states_exact(model: str, traced_build: TracedBuild) -> None:
    source = traced_controller(model)
    build = load_build(traced_build(model))
    twin = RobotTwin(build, noise=NOISE, seed=SEED, physics=False)
    result = twin.run(TRANSITIONS)
    assert sum(twin.noise_events.values()) >= 5  # the noise really hit the links
    assert result.stalled == []
    np.testing.assert_array_equal(
        result.state_array(build.legs, build.modules, TRANSITIONS),
        load_controller(source).states(TRANSITIONS),
    )
    mean, _ = result.period_stats()  # retries slow the robot down only a little
    estimate = max(m.timing.nominal_transition_s for m in build.manifest.modules)
    assert mean <= 1.25 * estimate
    gap = max(m.timing.longest_servo_gap_s for m in build.manifest.modules)
    assert max(result.servo_gaps.values()) <= 1.5 * gap


def test_the_serve_loop_s_waits_fit_each_other() -> None:
    """protocol/link.md §5: a slave listens longer than a master waits for a reply, so a
    master's retry meets a listen; the payload wait covers a byte at the pace."""
    for k in (link.CA, link.NN):
        assert k.listen > k.reply_wait
        assert k.payload_wait * 0.4 > link.byte_ms() + k.pace_ms - 1.0
        assert k.pace_ms * 1000 > 150 * 3.6  # a slow receiver's re-arm (item time x speed)
