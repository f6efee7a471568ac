"""Link noise on the robot twin: compiled programs stay exactly on the reference.

A slave lingers on the wire after its reply and answers the master's retries, so a lost or
damaged byte costs a retry, not a neighbour's state (protocol/link.md §4). Figures for other
noise levels and seeds: docs/compile.md "Link noise".
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import BuiltinBuild

from bstool.builtin import builtin_controller
from bstool.compile import timing
from bstool.controllers import load_controller
from bstool.wire import link
from hil_mock.robot import RobotTwin, load_build

TRANSITIONS = 30
NOISE = 0.002
SEED = 7


@pytest.mark.parametrize("model", ["ca2ddiff", "nnsin"])
def test_noisy_links_keep_the_states_exact(model: str, builtin_build: BuiltinBuild) -> None:
    source = builtin_controller(model)
    build = load_build(builtin_build(model))
    twin = RobotTwin(build, noise=NOISE, seed=SEED, physics=False)
    result = twin.run(TRANSITIONS)
    assert sum(twin.noise_events.values()) >= 5  # the noise really hit the links
    assert result.stalled == []
    np.testing.assert_array_equal(
        result.state_array(build.legs, build.modules, TRANSITIONS),
        load_controller(source).states(TRANSITIONS),
    )
    mean, _ = result.period_stats()  # retries do not slow the robot down
    assert abs(mean - build.period) <= 0.03 * build.period
    assert max(result.servo_gaps.values()) <= 0.025


def test_linger_and_recovery_constants_fit_the_masters_retries() -> None:
    """The waits that make retries safe (protocol/link.md §4), in 0.4 ms units: a master leaves
    ``ReplyBase`` (+ statements) between the last byte it got and its next try."""
    longest_pulse = 2.6 / timing.SERIN_UNIT_MS  # the longest servo pulse, with margin
    # after a partial frame the timeout restarts: pulse + listening must end before the next try
    assert timing.SLAVE_BASE_UNITS < link.REPLY_BASE_UNITS
    assert link.RECOVER_UNITS < link.REPLY_BASE_UNITS
    assert link.LINGER_UNITS + longest_pulse < link.REPLY_BASE_UNITS
    # ... and the recovery listen, begun within SlaveBase of a request's end, outlasts the gap
    assert timing.SLAVE_BASE_UNITS + link.RECOVER_UNITS - longest_pulse > link.REPLY_BASE_UNITS + 2
    # the linger hears a retry even if its header is lost: it outlasts the retry's second byte
    linger = link.LINGER_LISTENS * link.LINGER_UNITS * timing.SERIN_UNIT_MS
    assert linger > timing.retry_after_ms() + link.byte_ms() + 1.0
