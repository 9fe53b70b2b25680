"""Typed rule state: one object per owner and class, made on first use, held as given
(a factor's learned state), found without making one."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgm.core.learned import LearnedState
from pgm.inference.state import ProposalState, StateSlots


@dataclass
class Count(LearnedState):
    seen: int = 0


def test_get_makes_one_state_per_owner_and_class():
    slots = StateSlots()
    a = slots.get("x", ProposalState)
    assert slots.get("x", ProposalState) is a and slots.get("y", ProposalState) is not a
    assert slots.find("x", Count) is None and slots.find("z", ProposalState) is None


def test_hold_keeps_a_given_state_under_its_class():
    slots = StateSlots()
    c = Count(seen=3)
    assert slots.hold("colour", c) is c and slots.find("colour", Count) is c
    assert slots.get("colour", Count) is c  # not replaced by a new one
    assert "colour: Count" in repr(slots)


def test_a_proposal_mass_is_read_once():
    s = ProposalState(prior_log_mass=np.float64(-2.0))
    assert s.take() == -2.0 and s.take() is None
