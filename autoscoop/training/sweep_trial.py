"""One trial of a sweep, as Ray Tune runs it in a worker: an ordinary ``autoscoop train`` run.

:func:`run_trial` is Tune's function trainable. It trains into ``RUNS_DIR/TRIAL_ID`` with
:func:`autoscoop.training.run.train` (the same entry point, run directory and files as ``autoscoop
train``, so ``autoscoop eval --policy RUNS_DIR/TRIAL_ID`` loads it) and reports each periodic evaluation to
Tune as it comes (:func:`report_evaluation`): its episode, delivered fill, fill factor and success, and the
run's best delivered fill so far (``score``, the metric the sweep ranks by and ASHA stops on), with a Tune
checkpoint holding the evaluated actor. The last evaluation is reported once the run has written its final
files (:func:`report_finished`), so a trial Tune stops there is a finished run.

A trial Tune starts again (its driver was killed, ``autoscoop sweep --resume``) picks up its run directory:
one that finished is not trained again (its final evaluation is reported once more), one that did not is
continued with :func:`autoscoop.training.run.resume` (from its last checkpoint, as ``train --resume``).
"""

from __future__ import annotations

import json
import math
import shutil
import tempfile
from functools import partial
from pathlib import Path
from typing import Any

from autoscoop.training.callbacks import Evaluation
from autoscoop.training.checkpoints import read_run_json
from autoscoop.training.run import TrainArgs, resume, train
from autoscoop.training.sweep_results import plain, read_evaluations
from autoscoop.training.sweep_space import hyper_text

TRIAL_FILE = "trial.json"
"""in each Tune checkpoint: the trial's run directory, episode and score (beside the evaluated actor)."""


def run_trial(params: dict[str, Any]) -> None:
    """Tune's trainable: train (or continue) this trial's run directory, reporting each evaluation.

    Args:
        params: the trial's resolved ``param_space`` (:func:`autoscoop.training.sweep.param_space`):
            ``job`` (``runs_dir``, ``algo``, ``recipe``, ``episodes``, ``eval_every``, ``eval_episodes``,
            ``checkpoint_every``, ``command``), ``seed``, ``config`` (config key: value) and ``hyper``
            (algorithm key: value).
    """
    from ray import tune  # noqa: PLC0415 - optional extra

    job = params["job"]
    trial_id = tune.get_context().get_trial_id()
    run_dir = Path(job["runs_dir"]) / trial_id
    episodes = int(job["episodes"])
    status = read_run_json(run_dir).get("status") if (run_dir / "run.json").is_file() else None
    report = partial(report_evaluation, run_dir, last_episode=episodes)
    if status is None:
        train(TrainArgs(algo=job["algo"], recipe=job["recipe"], episodes=episodes, seed=int(plain(params["seed"])),
                        overrides={key: plain(value) for key, value in params["config"].items()},
                        hyper={key: hyper_text(plain(value)) for key, value in params["hyper"].items()},
                        out=run_dir, checkpoint_every=int(job["checkpoint_every"]), eval_every=int(job["eval_every"]),
                        eval_episodes=int(job["eval_episodes"]), progress=False, on_evaluation=report,
                        command=f"{job['command']} (trial {trial_id})"))
    elif status != "finished":
        resume(run_dir, progress=False, on_evaluation=report)
    # a run trained to the end before its driver went is reported, not trained again
    report_finished(run_dir)


def metrics_of(evaluation: Evaluation) -> dict[str, Any]:
    """What a trial reports to Tune of one evaluation (fractions in [0, 1]; ``episode``: training episodes done)."""
    metrics = {"episode": evaluation.episode, "delivered_fill": evaluation.delivered_fill,
               "fill_factor": evaluation.fill_factor, "success": evaluation.success, "score": evaluation.best_score}
    if not math.isnan(evaluation.cycle_time_s):
        metrics["cycle_time_s"] = evaluation.cycle_time_s
    return metrics


def report_evaluation(run_dir: Path, evaluation: Evaluation, last_episode: int | None = None) -> None:
    """Report an evaluation of ``run_dir`` to Tune, with a checkpoint: the evaluated actor and :data:`TRIAL_FILE`.

    The evaluation at ``last_episode`` (the run's end) is left to :func:`report_finished`, after the run has
    written its final files: Tune may stop a trial at any report (ASHA does at its last episode), and a run
    stopped there would not be finished.
    """
    if last_episode is not None and evaluation.episode >= last_episode:
        return
    _report(run_dir, metrics_of(evaluation), evaluation.actor)


def report_finished(run_dir: Path) -> None:
    """Report a finished run to Tune from its files: its last evaluation, and its best score (``score``), with a
    checkpoint holding the kept policy."""
    info = read_run_json(run_dir)
    rows = read_evaluations(run_dir)
    last = rows[-1] if rows else {}
    metrics = {"episode": int(info["episodes"]), "score": float(info.get("best_score", math.nan)),
               **{key: float(last.get(key, math.nan)) for key in ("delivered_fill", "fill_factor", "success")}}
    if last.get("cycle_time_s") not in (None, "", "nan"):
        metrics["cycle_time_s"] = float(last["cycle_time_s"])
    policy = run_dir / "policy.safetensors"
    _report(run_dir, metrics, policy if policy.is_file() else None)


def _report(run_dir: Path, metrics: dict[str, Any], actor: Path | None) -> None:
    """``tune.report`` with a checkpoint of ``actor`` (+ its sidecar) and :data:`TRIAL_FILE`."""
    from ray import tune  # noqa: PLC0415 - optional extra

    with tempfile.TemporaryDirectory(prefix="autoscoop-trial-") as folder:
        if actor is not None:
            for suffix in (".safetensors", ".json"):
                shutil.copyfile(actor.with_suffix(suffix), Path(folder) / f"actor{suffix}")
        (Path(folder) / TRIAL_FILE).write_text(json.dumps({"run_dir": str(run_dir), **metrics}) + "\n")
        tune.report(metrics, checkpoint=tune.Checkpoint.from_directory(folder))
