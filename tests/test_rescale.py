"""Moving a controller to a loader of another size: the Froude scaling folded into the first layer answers the
scaled input exactly as the original answered the unscaled one; a critic's privileged inputs are left alone."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from autoscoop.agents.networks import PaperActor
from autoscoop.agents.rescale import fold_input_factors, rescaled_actor
from autoscoop.cli import main
from autoscoop.core.state import (
    FROUDE_EXPONENTS,
    STATE_NAMES,
    STATE_UNITS,
    actor_input_normalization,
    actor_input_size,
    froude_input_factors,
)


@settings(max_examples=25, deadline=None)
@given(scale=st.floats(0.3, 3.0), history=st.sampled_from([1, 3]), seed=st.integers(0, 2**16))
def test_a_rescaled_actor_answers_the_scaled_state_as_the_original_answered_the_state(scale, history, seed):
    torch.manual_seed(seed)
    original = PaperActor(history_steps=history).eval()
    moved = rescaled_actor(copy.deepcopy(original), scale)
    centre, spread = actor_input_normalization(history)
    state = torch.as_tensor(centre + spread * np.random.default_rng(seed).uniform(-1, 1, (64, centre.size)),
                            dtype=torch.float32)
    factors = torch.as_tensor(froude_input_factors(scale, history), dtype=torch.float32)
    with torch.no_grad():
        assert torch.allclose(moved(state * factors), original(state), atol=2e-5)
        if abs(scale - 1.0) > 0.05:  # and it is another actor: the original is lost on the scaled state
            assert not torch.allclose(original(state * factors), original(state), atol=1e-3)


def test_the_fold_leaves_the_inputs_after_the_actor_input_alone():
    torch.manual_seed(0)
    layer = torch.nn.Linear(12 + 5, 7)
    before = layer.weight.detach().clone()
    centre, spread = actor_input_normalization(1)
    fold_input_factors(layer, froude_input_factors(1.5, 1), centre, spread)
    assert torch.equal(layer.weight[:, 12:], before[:, 12:])  # the privileged numbers
    assert not torch.equal(layer.weight[:, :12], before[:, :12])


def test_the_exponents_follow_the_units():
    by_unit = {"-": 0.0, "m": 1.0, "rad": 0.0}
    for name, unit, exponent in zip(STATE_NAMES, STATE_UNITS, FROUDE_EXPONENTS, strict=True):
        if name == "v":
            assert exponent == 0.5  # a speed: length / time, time as sqrt(S)
        elif name == "dv":
            assert exponent == 0.0  # an acceleration times the same control period
        elif name in ("dlift", "dtilt"):
            assert exponent == -0.5  # an angular speed times the same control period
        else:
            assert exponent == by_unit[unit], name
    assert froude_input_factors(2.0, 3).size == actor_input_size(3)
    assert np.all(froude_input_factors(2.0, 3)[-9:] == 1.0)  # the commands of the history
    with pytest.raises(ValueError, match="positive"):
        froude_input_factors(0.0, 1)


def test_a_length_scale_without_another_machine_is_refused(capsys):
    assert main(["adapt", "--policy", "default", "--length-scale", "1.5", "--episodes", "2"]) == 2
    assert "--length-scale scales a policy of another machine; give it with --from-machine" in capsys.readouterr().err
