"""Run a sweep on Ray Tune: trials of ``autoscoop train`` over a search space, embedded on this machine or on
a Ray cluster; continue an interrupted one.

A sweep's folder ``OUT``:

| path | what |
|---|---|
| sweep_plan.json | the checked space, ``--trials``, ``--episodes``, and each driver run (start, Ray, wall time) |
| tune/ | Tune's experiment (its state, each trial's results and checkpoints): what ``--resume`` restores |
| runs/TRIAL_ID/ | each trial's run directory, as ``autoscoop train`` writes it |

Without an address Ray starts embedded (``ray.init(address="local")``: a new instance of this process,
never one already running) and stops with the sweep; with one, the sweep's trials run on that cluster,
and ``OUT`` must be storage every node reads and writes at the same path. Resuming uses Tune's own
restore (:meth:`ray.tune.Tuner.restore`): trials it recorded as finished are not started again; the
others continue their run directories (:mod:`autoscoop.training.sweep_trial`).
"""

from __future__ import annotations

import logging
import os
import socket
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from autoscoop.core.safe_files import read_json, write_json_atomically
from autoscoop.core.version import __version__
from autoscoop.training.sweep_results import TrialRow, collect_row
from autoscoop.training.sweep_space import Distribution, SweepSpace, check_episodes, plan_trials, space_from_dict
from autoscoop.training.sweep_trial import run_trial

PLAN_FILE = "sweep_plan.json"
"""the sweep's settings and driver runs, in ``OUT``."""
PLAN_FORMAT = "autoscoop-sweep/1"
MAX_PLAN_BYTES = 16 << 20
"""cap of a sweep plan file, bytes."""
TUNE_NAME = "tune"
"""Tune's experiment folder, in ``OUT``."""
RUNS_DIR = "runs"
"""the trials' run directories, in ``OUT``."""
CPUS_PER_TRIAL = 1
"""each trial trains one environment on one thread (``torch.set_num_threads(1)``)."""
INSTALL_HINT = "pip install 'autoscoop[sweep]'"


@dataclass
class SweepArgs:
    """What ``autoscoop sweep`` was asked for."""

    space: SweepSpace
    """the checked search space."""
    trials: int
    """trials in all (a whole number of passes over the space's grid)."""
    episodes: int
    """training episodes per trial."""
    out: Path
    """the sweep's folder."""
    address: str | None = None
    """a Ray cluster's address (``HOST:PORT``); ``None``: Ray embedded in this process."""
    num_cpus: int | None = None
    """CPUs embedded Ray may use (trials at once, one CPU each); ``None``: all of this machine's."""
    max_concurrent: int | None = None
    """most trials running at once; ``None``: as many as the CPUs allow."""
    space_file: str = ""
    """where the space was read (recorded)."""
    command: str = ""
    """the command line (recorded in each trial's ``run.json``)."""


@dataclass
class SweepResult:
    """A sweep's trials and its wall times."""

    rows: list[TrialRow]
    plan: dict[str, Any]
    """``sweep_plan.json`` as it stands at the end."""
    wall_s: float
    """this driver run's wall time (s)."""
    ray: str
    """where the trials ran: ``embedded Ray (N CPUs)`` or ``the Ray cluster at ADDRESS``."""
    errors: list[str] = field(default_factory=list)
    """one line per failed trial."""

    @property
    def total_wall_s(self) -> float:
        """Wall time over every driver run (s); a killed run counts to its last recorded trial event."""
        return sum(float(s.get("wall_s") or 0.0) for s in self.plan["sessions"])


def require_ray() -> None:
    """Raises ValueError (exit 2) naming the extra to install when Ray Tune is missing."""
    try:
        import ray.tune  # noqa: F401, PLC0415 - optional extra
    except ImportError as error:
        raise ValueError(f"autoscoop sweep needs Ray Tune, which is not installed ({error}): {INSTALL_HINT}") from None


def check_address(address: str, timeout_s: float = 5.0) -> None:
    """Fail at once (ValueError, exit 2) where nothing listens at ``HOST:PORT`` (``ray.init`` would retry for
    minutes). Other forms Ray takes (``auto``, ``ray://...``) are left to Ray."""
    host, sep, port = address.rpartition(":")
    if "://" in address or not sep:
        return
    if not host or not port.isdigit():
        raise ValueError(f"--address {address}: expected HOST:PORT, e.g. 127.0.0.1:6379 (`ray start --head` prints it)")
    try:
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except OSError as error:
        raise ValueError(f"--address {address}: no Ray head answers there ({error}); start one with "
                         f"`ray start --head --port={port}` (docs/sweep.md)") from None


def read_plan(out: Path) -> dict[str, Any]:
    """``OUT/sweep_plan.json``.

    Raises:
        ValueError: no sweep there, or the file is not one autoscoop wrote.
    """
    path = Path(out) / PLAN_FILE
    if not path.is_file():
        raise ValueError(f"--resume {out}: holds no sweep to resume (no {PLAN_FILE}); start one with --out {out}")
    plan = read_json(path, "sweep plan", MAX_PLAN_BYTES)
    if not isinstance(plan, dict) or plan.get("format") != PLAN_FORMAT:
        raise ValueError(f"{path}: not an autoscoop sweep plan (format {PLAN_FORMAT!r})")
    return plan


def _write_plan(out: Path, plan: dict[str, Any]) -> None:
    write_json_atomically(out / PLAN_FILE, plan)


def record_session_time(out: str | Path) -> None:
    """Set the last driver run's wall time in ``sweep_plan.json`` to now (called as trials report, so a killed
    driver's time is known to its last trial event)."""
    out = Path(out)
    plan = read_plan(out)
    session = plan["sessions"][-1]
    session["wall_s"] = round(time.time() - session["started_unix"], 1)
    _write_plan(out, plan)


def start_sweep(args: SweepArgs) -> SweepResult:
    """Start a new sweep in ``args.out`` and run it to the end.

    Raises:
        ValueError: ``args.out`` already holds a sweep (``--resume`` continues it), or bad ``--trials``/``--episodes``.
    """
    out = args.out.resolve()
    num_samples = plan_trials(args.space, args.trials)
    check_episodes(args.space, args.episodes)
    if (out / PLAN_FILE).exists():
        raise ValueError(f"--out {args.out} already holds a sweep ({PLAN_FILE}); use --resume {args.out} to continue "
                         "it, or another --out")
    out.mkdir(parents=True, exist_ok=True)
    plan = {"format": PLAN_FORMAT, "autoscoop_version": __version__, "space_file": args.space_file,
            "space": args.space.to_dict(), "trials": args.trials, "episodes": args.episodes,
            "num_samples": num_samples, "command": args.command, "sessions": []}
    return _drive(out, plan, args, resumed=False)


def resume_sweep(args: SweepArgs) -> SweepResult:
    """Continue the sweep in ``args.out`` (its recorded space, trials and episodes; ``args``' must match)."""
    out = args.out.resolve()
    plan = read_plan(out)
    return _drive(out, plan, args, resumed=True)


def check_resume_matches(plan: dict[str, Any], space: SweepSpace | None, trials: int | None,
                         episodes: int | None) -> None:
    """Refuse a ``--resume`` whose ``--space``, ``--trials`` or ``--episodes`` differ from the recorded ones.

    Raises:
        ValueError: naming the option, both values and the plan file.
    """
    recorded = {"--trials": plan["trials"], "--episodes": plan["episodes"]}
    for option, value in (("--trials", trials), ("--episodes", episodes)):
        if value is not None and value != recorded[option]:
            raise ValueError(f"{option} {value} does not match the sweep being resumed ({PLAN_FILE} records "
                             f"{recorded[option]}); leave {option} out to resume it as it was")
    if space is not None and space.to_dict() != plan["space"]:
        raise ValueError(f"--space differs from the space the sweep was started with (recorded in {PLAN_FILE}); "
                         "a resumed sweep keeps its space: leave --space out, or start a new sweep (another --out)")


def _drive(out: Path, plan: dict[str, Any], args: SweepArgs, resumed: bool) -> SweepResult:
    """Start or connect to Ray, run (or restore) the Tune experiment, collect the rows; Ray is left as found."""
    os.environ.setdefault("RAY_AIR_NEW_OUTPUT", "0")  # the classic reporter, silent at verbose=0
    os.environ.setdefault("TUNE_GLOBAL_CHECKPOINT_S", "2")  # Tune's experiment state every 2 s: little to redo
    os.environ.setdefault("TUNE_WARN_EXCESSIVE_EXPERIMENT_CHECKPOINT_SYNC_THRESHOLD_S", "0")  # small state: no warning
    import ray  # noqa: PLC0415 - optional extra
    from ray import tune  # noqa: PLC0415 - optional extra

    space = space_from_dict(plan["space"])
    ray_name = f"the Ray cluster at {args.address}" if args.address else f"embedded Ray ({args.num_cpus or os.cpu_count()} CPUs)"
    started = time.time()
    plan["sessions"].append({"started": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "started_unix": round(started, 3),
                             "ray": ray_name, "resumed": resumed, "wall_s": 0.0})
    _write_plan(out, plan)
    if args.address:
        ray.init(address=args.address, log_to_driver=False, logging_level=logging.WARNING)
    else:
        ray.init(address="local", num_cpus=args.num_cpus or os.cpu_count(), include_dashboard=False,
                 log_to_driver=False, logging_level=logging.WARNING)
    try:
        trainable = tune.with_resources(run_trial, {"cpu": CPUS_PER_TRIAL})
        experiment = out / TUNE_NAME
        if resumed and tune.Tuner.can_restore(str(experiment)):
            print(f"resuming the sweep in {out} (Tune's experiment {experiment})", flush=True)
            tuner = tune.Tuner.restore(str(experiment), trainable, resume_unfinished=True, resume_errored=True)
        else:
            if resumed:
                print(f"{experiment}: no Tune experiment to restore (stopped before Tune recorded one); "
                      "starting its trials", flush=True)
            tuner = _new_tuner(tune, trainable, space, plan, out, args)
        grid = tuner.fit()
        rows, errors = _rows(grid, space, out)
    finally:
        ray.shutdown()
    record_session_time(out)
    plan = read_plan(out)
    return SweepResult(rows=rows, plan=plan, wall_s=time.time() - started, ray=ray_name, errors=errors)


def _new_tuner(tune: Any, trainable: Any, space: SweepSpace, plan: dict[str, Any], out: Path, args: SweepArgs) -> Any:
    from ray.tune.schedulers import ASHAScheduler  # noqa: PLC0415 - optional extra
    from ray.tune.search import BasicVariantGenerator  # noqa: PLC0415 - optional extra

    episodes = int(plan["episodes"])
    job = {"runs_dir": str(out / RUNS_DIR), "algo": space.algo, "recipe": space.recipe, "episodes": episodes,
           **space.train.to_dict(), "command": plan["command"] or "autoscoop sweep"}
    scheduler = None
    if space.asha is not None:
        scheduler = ASHAScheduler(time_attr="episode", max_t=episodes, grace_period=space.asha.grace_period,
                                  reduction_factor=space.asha.reduction_factor)
    tune_config = tune.TuneConfig(metric="score", mode="max", num_samples=int(plan["num_samples"]),
                                  max_concurrent_trials=args.max_concurrent, scheduler=scheduler,
                                  search_alg=BasicVariantGenerator(random_state=space.draw_seed),
                                  trial_name_creator=trial_name, trial_dirname_creator=trial_name)
    run_config = tune.RunConfig(name=TUNE_NAME, storage_path=str(out), verbose=0,
                                callbacks=[progress_callback(str(out), int(plan["trials"]), episodes,
                                                             list(space.swept()))],
                                checkpoint_config=tune.CheckpointConfig(num_to_keep=2),
                                failure_config=tune.FailureConfig(max_failures=1))
    return tune.Tuner(trainable, param_space=param_space(space, job), tune_config=tune_config, run_config=run_config)


def tune_distribution(dist: Distribution) -> Any:
    """Tune's search-space object for a setting (``tune.choice`` ...; the value itself when fixed)."""
    from ray import tune  # noqa: PLC0415 - optional extra

    if dist.kind == "fixed":
        return dist.values[0]
    if dist.kind == "choice":
        return tune.choice(list(dist.values))
    if dist.kind == "grid":
        return tune.grid_search(list(dist.values))
    return {"uniform": tune.uniform, "loguniform": tune.loguniform}[dist.kind](*dist.values)


def param_space(space: SweepSpace, job: dict[str, Any]) -> dict[str, Any]:
    """Tune's ``param_space``: the constant ``job`` (what every trial shares, see
    :func:`autoscoop.training.sweep_trial.run_trial`), the seed grid and the config and algorithm settings."""
    from ray import tune  # noqa: PLC0415 - optional extra

    seeds = list(space.seeds)
    return {"job": job, "seed": tune.grid_search(seeds) if len(seeds) > 1 else seeds[0],
            "config": {key: tune_distribution(dist) for key, dist in space.config.items()},
            "hyper": {key: tune_distribution(dist) for key, dist in space.hyper.items()}}


def trial_name(trial: Any) -> str:
    """A trial's name and Tune folder: its id (its run directory is ``OUT/runs/TRIAL_ID``)."""
    return str(trial.trial_id)


def _rows(grid: Any, space: SweepSpace, out: Path) -> tuple[list[TrialRow], list[str]]:
    """One row per trial of Tune's result grid, from its run directory; the failed trials' errors."""
    rows, errors = [], []
    swept = list(space.swept())
    for result in grid:
        trial_id = Path(result.path).name
        error = ""
        if result.error is not None:
            error = (str(result.error).strip().splitlines() or [type(result.error).__name__])[-1][:300]
            errors.append(f"{trial_id}: {error}")
        rows.append(collect_row(trial_id, result.config or {}, swept, out / RUNS_DIR / trial_id, error))
    return sorted(rows, key=lambda r: r.trial_id), errors


def progress_callback(out: str, total: int, episodes: int, swept: list[str]) -> Any:
    """A Tune callback printing one line per trial start, evaluation and end (Tune's own output is off), and
    keeping the driver run's wall time in ``sweep_plan.json``. It keeps no state of its own (Tune's restore
    brings back the callback it pickled at the start)."""
    from ray import tune  # noqa: PLC0415 - optional extra

    def done_count(trials: list[Any], trial: Any) -> str:
        finished = {t.trial_id for t in trials if t.is_finished()} | {trial.trial_id}
        return f"[{len(finished)}/{total} done]"

    def settings(trial: Any) -> str:
        values = {**trial.config.get("config", {}), **trial.config.get("hyper", {})}
        shown = [f"{key}={short(values[key])}" for key in swept if key in values]
        return ", ".join([*shown, f"seed={trial.config.get('seed')}"])

    class SweepProgress(tune.Callback):
        def on_trial_start(self, iteration: int, trials: list[Any], trial: Any, **info: Any) -> None:
            print(f"trial {trial.trial_id} started: {settings(trial)}", flush=True)

        def on_trial_result(self, iteration: int, trials: list[Any], trial: Any, result: dict[str, Any],
                            **info: Any) -> None:
            print(f"trial {trial.trial_id} episode {result.get('episode')}/{episodes}: delivered fill "
                  f"{result.get('delivered_fill', float('nan')):.3f}, success {result.get('success', float('nan')):.2f}, "
                  f"best {result.get('score', float('nan')):.3f}", flush=True)
            record_session_time(out)

        def on_trial_complete(self, iteration: int, trials: list[Any], trial: Any, **info: Any) -> None:
            last = trial.last_result or {}
            print(f"{done_count(trials, trial)} trial {trial.trial_id} ended at episode {last.get('episode')}: "
                  f"score {last.get('score', float('nan')):.3f} ({settings(trial)})", flush=True)
            record_session_time(out)

        def on_trial_error(self, iteration: int, trials: list[Any], trial: Any, **info: Any) -> None:
            print(f"{done_count(trials, trial)} trial {trial.trial_id} FAILED ({settings(trial)}); "
                  f"its error: {trial.error_file}", file=sys.stderr, flush=True)
            record_session_time(out)

    return SweepProgress()


def short(value: Any) -> str:
    """A setting's value as a line shows it (floats to 4 significant digits)."""
    return f"{value:.4g}" if isinstance(value, float) else str(value)
