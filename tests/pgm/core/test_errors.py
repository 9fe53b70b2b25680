"""A signal is not allowed to cut a block that must finish (a video frame being muxed,
the file's index being written); it is raised when the block ends."""

import signal

import pytest

from pgm.core.errors import Interrupted, interrupt, uninterrupted


def test_a_signal_inside_an_uninterrupted_block_is_raised_when_it_ends():
    done = []
    with pytest.raises(Interrupted) as info:
        with uninterrupted():
            with uninterrupted():  # nested: held until the outermost block ends
                interrupt(signal.SIGTERM)
                done.append("inner")
            done.append("outer")
    assert done == ["inner", "outer"] and info.value.signum == signal.SIGTERM
    with uninterrupted():  # nothing pending is left behind
        pass
    with pytest.raises(Interrupted):
        interrupt(signal.SIGINT)  # outside a block: at once
