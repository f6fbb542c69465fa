"""Teacher-student training: distil a deployable actor from a teacher that sees the drawn world (DAgger).

The teacher is a run of ``experiments/teacher_feasibility.py train``: the paper's policy whose actor reads
the actor's input and the simulator's privileged numbers (:mod:`autoscoop.envs.privileged`: the true load,
the particle mass, the link's delay). The student is the paper's actor on the robot's readings alone (with
the teacher's history of states and commands), as every shipped actor is. Each iteration runs episodes of
the randomised world in which the student acts (the teacher, with probability ``beta`` per episode, which
shrinks each iteration), labels every state the student saw with the teacher's action, adds them to the
data set, and fits the student to all of it (mean squared error on the actions). The student starts from
``--init`` (an actor file of the same history) or from scratch. With ``--heavy-teacher``, a second teacher
labels (and drives) the episodes of heavy earth, from ``--heavy-from`` kg per particle. With ``--robot-teacher``
the teacher is an ordinary run's actor, which reads what the student reads (distillation alone, no privilege).

Each iteration writes ``DIR/iteration_K.safetensors`` (a policy file ``autoscoop stress --policy`` runs) and
``DIR/dagger.json`` (per iteration: episodes, labelled states, training loss, and the student's own success,
fill and overload over that iteration's student episodes); the last iteration's actor is
``DIR/policy.safetensors``.

    .venv/bin/python experiments/dagger_student.py --teacher runs/teacher-s10 --init runs/RUN/policy.safetensors \\
        --iterations 8 --episodes 40 --out runs/dagger-s10
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import torch

from autoscoop.agents.networks import PaperActor
from autoscoop.agents.policy_files import load_actor, save_actor
from autoscoop.core.config import ScoopConfig
from autoscoop.core.safe_files import write_json_atomically
from autoscoop.core.state import actor_input_size
from autoscoop.envs.privileged import NOMINAL_PARTICLE_MASS_KG, PRIVILEGED_NAMES
from autoscoop.envs.rollout import rollout


class MixedPolicy:
    """Acts as the teacher or the student (chosen per episode), and records every actor input with the
    teacher's action for it. With a ``heavy_teacher``, that one teaches (and acts) in the episodes whose
    particle mass is ``heavy_from_kg`` or more (read from the privileged numbers)."""

    def __init__(self, teacher, student: PaperActor, actor_size: int, frame: str, heavy_teacher=None,
                 heavy_from_kg: float = float("inf")) -> None:
        self.teacher, self.student, self.actor_size = teacher, student, actor_size
        self.heavy_teacher, self.heavy_from_kg = heavy_teacher, heavy_from_kg
        self.state_frame = frame
        self.name = "dagger"
        self.use_teacher = False
        self.inputs: list[np.ndarray] = []
        self.labels: list[np.ndarray] = []

    def reset(self) -> None:
        self.teacher.reset()
        if self.heavy_teacher is not None:
            self.heavy_teacher.reset()

    def teacher_for(self, observation: np.ndarray):
        """The heavy teacher where the episode's particle mass is ``heavy_from_kg`` or more, else the teacher."""
        density = observation[self.actor_size + PRIVILEGED_NAMES.index("relative_density")]
        heavy = self.heavy_teacher is not None and density * NOMINAL_PARTICLE_MASS_KG >= self.heavy_from_kg
        return self.heavy_teacher if heavy else self.teacher

    def act(self, observation: np.ndarray) -> np.ndarray:
        observation = np.asarray(observation, dtype=np.float32)
        teacher_action = np.asarray(self.teacher_for(observation).act(observation), dtype=np.float32)
        actor_input = observation[:self.actor_size]
        self.inputs.append(actor_input)
        self.labels.append(teacher_action)
        if self.use_teacher:
            return teacher_action
        with torch.no_grad():
            return self.student(torch.as_tensor(actor_input)[None]).numpy()[0]


class RobotStateTeacher:
    """An ordinary run's actor as the teacher: it reads the actor's input only (the privileged numbers after it
    are dropped), as the student does."""

    def __init__(self, actor: PaperActor, actor_size: int) -> None:
        self.actor, self.actor_size = actor, actor_size

    def reset(self) -> None:
        pass

    def act(self, observation: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return self.actor(torch.as_tensor(observation[:self.actor_size])[None]).numpy()[0]


def fit(student: PaperActor, inputs: np.ndarray, labels: np.ndarray, epochs: int, batch: int, lr: float,
        generator: torch.Generator) -> float:
    """Fit the student to the labels (mean squared error); the last epoch's mean loss."""
    student.train()
    optimizer = torch.optim.Adam(student.parameters(), lr=lr)
    x, y = torch.as_tensor(inputs), torch.as_tensor(labels)
    loss_sum = 0.0
    for _ in range(epochs):
        order = torch.randperm(len(x), generator=generator)
        loss_sum, batches = 0.0, 0
        for start in range(0, len(x), batch):
            index = order[start:start + batch]
            loss = torch.nn.functional.mse_loss(student(x[index]), y[index])
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            loss_sum += loss.item()
            batches += 1
        loss_sum /= batches
    student.eval()
    return loss_sum


def positive(text: str) -> int:
    """A whole number of 1 or more (argparse type)."""
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be 1 or more, got {value}")
    return value


def main(argv: list[str] | None = None) -> int:
    from stable_baselines3 import DDPG  # noqa: PLC0415
    from teacher_feasibility import TeacherPolicy  # noqa: PLC0415

    from autoscoop.agents.loading import SB3Policy  # noqa: PLC0415
    from autoscoop.training.checkpoints import read_run_json, read_run_yaml  # noqa: PLC0415
    from autoscoop.training.factories import make_training_env  # noqa: PLC0415

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--teacher", type=Path, required=True, help="teacher run directory (its policy.zip)")
    parser.add_argument("--robot-teacher", action="store_true",
                        help="--teacher is an ordinary run: its policy.safetensors (robot state only) teaches")
    parser.add_argument("--heavy-teacher", type=Path, default=None,
                        help="a teacher run for the episodes whose particle mass is --heavy-from or more")
    parser.add_argument("--heavy-from", type=float, default=0.36, help="particle mass from which the heavy teacher "
                        "teaches, kg (default 0.36)")
    parser.add_argument("--init", type=Path, default=None, help="the student's starting actor file")
    parser.add_argument("--iterations", type=positive, default=8)
    parser.add_argument("--episodes", type=positive, default=40, help="episodes per iteration")
    parser.add_argument("--beta", type=float, default=0.5, help="teacher's share of the first iteration's episodes")
    parser.add_argument("--beta-decay", type=float, default=0.5)
    parser.add_argument("--epochs", type=int, default=20)
    parser.add_argument("--batch", type=int, default=256)
    parser.add_argument("--lr", type=float, default=1e-3)
    parser.add_argument("--preset", default="robot", help="the randomised world the episodes are drawn from")
    parser.add_argument("--seed", type=int, default=100_000, help="first episode seed (outside stress's 0-99)")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)

    history = int((read_run_yaml(args.teacher, "hyperparams.yaml") or {}).get("history_steps", 1))
    frame = read_run_json(args.teacher).get("state_frame", "chassis")
    config = ScoopConfig().with_overrides({"randomize.preset": args.preset})
    env = make_training_env(config, privileged=True, history=history)
    def load_teacher(run: Path) -> SB3Policy:
        if int((read_run_yaml(run, "hyperparams.yaml") or {}).get("history_steps", 1)) != history:
            raise SystemExit(f"{run} reads another history than {args.teacher}")
        model = DDPG(TeacherPolicy, env, policy_kwargs={"history_steps": history}, device="cpu")
        model.set_parameters(str(run / "policy.zip"), device="cpu")
        return SB3Policy(model, run.name)

    if args.robot_teacher:
        robot_actor, _ = load_actor(args.teacher / "policy.safetensors")
        if robot_actor.history_steps != history:
            raise SystemExit(f"{args.teacher}/policy.safetensors reads another history than its hyperparams.yaml")
        teacher = RobotStateTeacher(robot_actor, actor_input_size(history))
    else:
        teacher = load_teacher(args.teacher)
    heavy_teacher = load_teacher(args.heavy_teacher) if args.heavy_teacher else None
    if args.init is not None:
        student, _ = load_actor(args.init)
        if student.history_steps != history:
            raise SystemExit(f"--init reads {student.history_steps} states, the teacher {history}")
    else:
        student = PaperActor(history_steps=history)
    student.eval()
    mixed = MixedPolicy(teacher, student, actor_input_size(history), frame, heavy_teacher, args.heavy_from)
    rng = np.random.default_rng(args.seed)
    generator = torch.Generator().manual_seed(args.seed)
    args.out.mkdir(parents=True, exist_ok=True)
    log: list[dict] = []
    all_inputs, all_labels = [], []
    seed = args.seed
    started = time.monotonic()
    for iteration in range(args.iterations):
        beta = args.beta * args.beta_decay ** iteration
        student_outcomes = []
        for _ in range(args.episodes):
            mixed.use_teacher = bool(rng.random() < beta)
            outcome = rollout(mixed, env, seed)
            seed += 1
            if not mixed.use_teacher:
                student_outcomes.append(outcome)
        all_inputs.extend(mixed.inputs)
        all_labels.extend(mixed.labels)
        mixed.inputs, mixed.labels = [], []
        loss = fit(student, np.array(all_inputs), np.array(all_labels), args.epochs, args.batch, args.lr, generator)
        meta = {"algo": "dagger", "teacher": args.teacher.name, "iteration": iteration,
                **({"heavy_teacher": args.heavy_teacher.name, "heavy_from_kg": args.heavy_from} if heavy_teacher else {}),
                "state_frame": frame, "seed": args.seed}
        save_actor(student, args.out / f"iteration_{iteration}.safetensors", meta)
        row = {"iteration": iteration, "beta": round(beta, 4), "states": len(all_inputs), "loss": round(loss, 5),
               "student_episodes": len(student_outcomes), "wall_s": round(time.monotonic() - started, 1)}
        if student_outcomes:
            row |= {"student_success": round(float(np.mean([o.success for o in student_outcomes])), 3),
                    "student_fill": round(float(np.mean([o.fill_factor for o in student_outcomes])), 3),
                    "student_overload": round(float(np.mean([o.overloaded for o in student_outcomes])), 3)}
        log.append(row)
        print(row, flush=True)
        write_json_atomically(args.out / "dagger.json", {"teacher": str(args.teacher), "init": str(args.init),
                                                         "heavy_teacher": str(args.heavy_teacher),
                                                         "args": {k: str(v) for k, v in vars(args).items()},
                                                         "iterations": log})
    save_actor(student, args.out / "policy.safetensors", meta)
    env.close()
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).parent))
    sys.exit(main())
