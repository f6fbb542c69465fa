"""ONNX export of the actor: parity with torch, inference time, and a controller that runs it without torch."""

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("onnxruntime")
pytest.importorskip("onnx")

from torch import nn  # noqa: E402

from autoscoop.agents.onnx_policy import OnnxPolicy  # noqa: E402
from autoscoop.core.state import STATE_CENTRE, STATE_SCALE  # noqa: E402
from autoscoop.deploy.export import PARITY_TOLERANCE, check_parity, export_onnx, exportable_actor, random_states  # noqa: E402


class ScaledPaperActor(nn.Module):
    """The paper's actor, built here: fixed input scaling, 100-80-60 with LayerNorm and ReLU, tanh output."""

    def __init__(self):
        super().__init__()
        self.register_buffer("centre", torch.as_tensor(STATE_CENTRE))
        self.register_buffer("scale", torch.as_tensor(STATE_SCALE))
        layers, n_in = [], 12
        for width in (100, 80, 60):
            layers += [nn.Linear(n_in, width), nn.LayerNorm(width), nn.ReLU()]
            n_in = width
        self.body = nn.Sequential(*layers)
        self.head = nn.Linear(n_in, 3)

    def forward(self, state):
        return torch.tanh(self.head(self.body((state - self.centre) / self.scale)))


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    torch.manual_seed(0)
    actor = ScaledPaperActor()
    with torch.no_grad():  # LayerNorm weights away from 1 and 0 so the test sees them
        for p in actor.parameters():
            p.add_(0.2 * torch.randn_like(p))
    path = export_onnx(actor, tmp_path_factory.mktemp("onnx") / "actor.onnx", {"policy_name": "random-actor"})
    return actor, path


def test_onnx_matches_torch_over_10000_random_states(exported, record_property):
    actor, path = exported
    report = check_parity(actor, path, random_states(10_000, seed=1), timing_steps=500)
    record_property("onnx_parity", json.dumps(report))
    print(f"max |onnx - torch| {report['max_abs_diff']:.2e}; step: onnxruntime "
          f"{report['onnxruntime_step']['median_us']:.0f} us, torch {report['torch_step']['median_us']:.0f} us")
    assert report["max_abs_diff"] <= PARITY_TOLERANCE and report["passed"]
    # both runtimes round in float32 about the same float64 network, by less than the tolerance
    assert 0.0 < report["torch_vs_float64"] <= PARITY_TOLERANCE and 0.0 < report["onnx_vs_float64"] <= PARITY_TOLERANCE
    assert report["onnxruntime_step"]["median_us"] < 5000  # far below the 0.25 s control period


def test_parity_fails_for_an_onnx_file_of_another_network(exported):
    actor, path = exported
    other = ScaledPaperActor()
    other.load_state_dict(actor.state_dict())
    with torch.no_grad():
        other.head.bias.add_(1e-3)  # a slightly different network than the file holds
    report = check_parity(other, path, random_states(200, seed=2), timing_steps=10)
    assert report["max_abs_diff"] > PARITY_TOLERANCE and not report["passed"]


def test_onnx_policy_acts_like_a_policy_and_keeps_its_metadata(exported):
    actor, path = exported
    policy = OnnxPolicy(path)
    assert policy.name == "random-actor" and policy.metadata["state_names"].startswith("w,tip_x")
    state = random_states(1, seed=3)[0]
    action = policy.act(state)
    assert action.shape == (3,) and np.all(np.abs(action) <= 1.0)
    with torch.no_grad():
        assert np.allclose(action, actor(torch.as_tensor(state[None]))[0].numpy(), atol=1e-5)


def test_a_foreign_onnx_file_is_refused_with_a_reason(tmp_path):
    import onnx
    from onnx import TensorProto, helper

    graph = helper.make_graph([helper.make_node("Identity", ["state"], ["action"])], "foreign",
                              [helper.make_tensor_value_info("state", TensorProto.FLOAT, [1, 12])],
                              [helper.make_tensor_value_info("action", TensorProto.FLOAT, [1, 12])])
    path = tmp_path / "other.onnx"
    onnx.save(helper.make_model(graph, ir_version=8, opset_imports=[helper.make_opsetid("", 17)]), str(path))
    with pytest.raises(ValueError, match="not an autoscoop policy export"):
        OnnxPolicy(path)
    with pytest.raises(ValueError, match="no such file"):
        OnnxPolicy(tmp_path / "missing.onnx")


def test_the_heuristic_has_nothing_to_export():
    from autoscoop.agents.loading import load_policy
    from autoscoop.core.config import ScoopConfig

    with pytest.raises(ValueError, match="no neural network to export"):
        exportable_actor(load_policy("heuristic", ScoopConfig()))


def test_the_controller_runs_an_onnx_policy_without_torch(exported):
    _, path = exported
    script = textwrap.dedent(f"""
        import sys
        sys.modules["torch"] = None  # any import of torch now fails
        from autoscoop.agents.loading import load_policy
        from autoscoop.core.config import ScoopConfig
        from autoscoop.deploy.controller import ControllerCore
        from autoscoop.deploy.robot_config import RobotNodeConfig
        task = ScoopConfig()
        core = ControllerCore(RobotNodeConfig(), load_policy({str(path)!r}, task), task)
        for t in (0.0, 0.1):
            core.joint_states(["lift", "tilt"], [0.23, 0.0], t)
            core.odometry(0.0, t)
            core.pile_range(0.3, t, 0.0, 4.0)
            core.bucket_torque(-1.0, t)
            core.lift_torque(-20.0, t)
        core.scoop(True, 0.1)
        command = core.update(0.1)
        assert command.mode == "running", command
        assert "torch" not in [m for m in sys.modules if sys.modules[m] is not None]
        print("ok", type(core.policy).__name__, command)
    """)
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]
    assert "ok OnnxPolicy" in result.stdout


def test_export_command_exports_a_saved_policy_file(tmp_path, capsys):
    """``autoscoop export`` on a trained policy's safe file (its actor with the state normalisation inside)."""
    from autoscoop.agents.networks import PaperActor
    from autoscoop.agents.policy_files import save_actor
    from autoscoop.cli import main

    torch.manual_seed(1)
    weights = save_actor(PaperActor(), tmp_path / "trained.safetensors", {"algo": "test"})
    out = tmp_path / "trained.onnx"
    assert main(["export", "--policy", str(weights), "--onnx", str(out), "--check-states", "2000",
                 "--json", str(tmp_path / "parity.json")]) == 0
    assert "max |onnx - torch|" in capsys.readouterr().out
    assert json.loads((tmp_path / "parity.json").read_text())["passed"] is True
    assert OnnxPolicy(out).name == "trained"
