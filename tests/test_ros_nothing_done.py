"""``ros sim`` and ``ros2 sim`` fail a run that achieved nothing: no scoop reached the terminal point, or no
command arrived from the controller (exit 3, ``--allow-empty`` 0). The middleware's node is replaced by one
that returns the episodes' outcomes, so the command's own decision is what is tested, without ROS."""

import pytest

from autoscoop.cli import main
from autoscoop.commands.options import EXIT_NOTHING_DONE
from autoscoop.deploy.sim_loop import SimRunStats
from autoscoop.envs.outcome import EpisodeOutcome


def outcome(seed, reached, fill=0.0):
    return EpisodeOutcome(seed=seed, fill_factor=fill, mass_kg=7.0 * fill, particles=int(fill * 23), success=reached
                          and fill >= 0.5, cycle_time_s=4.0 if reached and fill >= 0.5 else None, spilled=0,
                          physics_error=False, steps=32, episode_return=0.0, reached=reached)


class FakeNode:
    """A simulator node whose episodes ended as ``OUTCOMES`` say, after ``COMMANDS`` commands arrived."""

    OUTCOMES: list = []
    COMMANDS = 0

    def __init__(self, bridge, *args, **kwargs):
        self.bridge = bridge

    def run(self, episodes, seed=0, wait_for_controller_s=60.0):
        stats = SimRunStats(sim_s=[8.0] * len(self.OUTCOMES), wall_s=[8.0] * len(self.OUTCOMES),
                            commands_received=self.COMMANDS, controller_policy="default")
        return list(self.OUTCOMES), stats

    def stop(self):
        pass


@pytest.fixture(params=["ros", "ros2"])
def sim_command(request, monkeypatch):
    if request.param == "ros":
        import autoscoop.deploy.ros1.sim_node as node_module
    else:
        pytest.importorskip("cyclonedds")
        import autoscoop.commands.ros2_cmd as ros2_cmd
        import autoscoop.deploy.ros2.sim_node as node_module

        monkeypatch.setattr(ros2_cmd, "_stop_on_sigterm", lambda stop: None)
    monkeypatch.setattr(node_module, "SimNode", FakeNode)
    return request.param


@pytest.mark.parametrize("outcomes, commands, why", [
    ([outcome(0, False), outcome(1, False, 0.3)], 40, "no scoop reached the terminal point in 2 episode(s)"),
    ([outcome(0, False)], 0, "no command arrived from the controller"),
    ([], 0, "no episode finished"),
])
def test_a_simulator_run_that_achieved_nothing_exits_3_unless_allowed(sim_command, outcomes, commands, why,
                                                                      monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(FakeNode, "OUTCOMES", outcomes)
    monkeypatch.setattr(FakeNode, "COMMANDS", commands)
    argv = [sim_command, "sim", "--episodes", "2", "--json", str(tmp_path / "s.json")]
    assert main(argv) == EXIT_NOTHING_DONE
    assert why in capsys.readouterr().err
    assert main([*argv, "--allow-empty"]) == 0


def test_a_simulator_run_with_one_scoop_at_the_terminal_point_exits_0(sim_command, monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(FakeNode, "OUTCOMES", [outcome(0, False), outcome(1, True, 0.7)])
    monkeypatch.setattr(FakeNode, "COMMANDS", 60)
    assert main([sim_command, "sim", "--episodes", "2", "--json", str(tmp_path / "s.json")]) == 0
    assert (tmp_path / "s.json").stat().st_size
