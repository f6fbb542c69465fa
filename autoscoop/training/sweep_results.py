"""What a sweep's trials came to, read from their run directories; the best one's policy exported.

Each trial's numbers come from its run directory (``run.json``, ``evaluations.csv``, ``episodes.csv``), the
files ``autoscoop train`` writes: the score is the delivered fill of the policy the run kept (the best
periodic evaluation, as training selects it), with that evaluation's fill factor and success.
"""

from __future__ import annotations

import csv
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from autoscoop.agents.policy_files import load_actor, save_actor
from autoscoop.training.checkpoints import read_run_json

STATUSES = ("finished", "stopped early", "error", "not started")
"""A trial's ``status``: trained all its episodes; stopped by ASHA (no error) before them; failed; never ran."""


@dataclass
class TrialRow:
    """One trial of a sweep."""

    trial_id: str
    """Tune's trial id; its run directory is ``RUNS_DIR/TRIAL_ID``."""
    settings: dict[str, Any]
    """the swept settings' values (config and algorithm keys as the space file writes them)."""
    seed: int
    """the training seed."""
    score: float
    """the kept policy's delivered fill, in [0, 1] (NaN before any evaluation)."""
    fill_factor: float
    """mean fill factor of that evaluation (mass in the bucket / rated load; NaN before any)."""
    success: float
    """success rate of that evaluation, in [0, 1] (NaN before any)."""
    best_episode: int | None
    """the training episode of that evaluation."""
    episodes_done: int
    """training episodes done (rows of ``episodes.csv``)."""
    wall_s: float
    """the run's training wall time (s), across resumes."""
    status: str
    """one of :data:`STATUSES`."""
    run_dir: Path
    """the trial's run directory (``autoscoop eval --policy RUN_DIR`` loads it)."""
    error: str = ""
    """the error's last line, for a failed trial."""

    def as_dict(self) -> dict[str, Any]:
        """Plain data (the JSON's ``rows``)."""
        data = asdict(self)
        data["run_dir"] = str(self.run_dir)
        return data


def plain(value: Any) -> Any:
    """A drawn value as plain Python (a numpy scalar as its number; lists item by item)."""
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    item = getattr(value, "item", None)
    return item() if callable(item) and not isinstance(value, (int, float, str, bool)) else value


def _csv_rows(path: Path) -> list[dict[str, str]]:
    """The rows of a CSV file with a header (none if there is no such file)."""
    if not path.is_file():
        return []
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def read_evaluations(run_dir: Path) -> list[dict[str, str]]:
    """The rows of a run's ``evaluations.csv`` (none if it has none)."""
    return _csv_rows(Path(run_dir) / "evaluations.csv")


def collect_row(trial_id: str, params: dict[str, Any], swept: list[str], run_dir: Path, error: str = "") -> TrialRow:
    """A trial's row from its resolved settings (``params``, as :func:`autoscoop.training.sweep_trial.run_trial`
    gets them) and its run directory; ``swept``: the keys to list under ``settings``."""
    values = {**params.get("config", {}), **params.get("hyper", {})}
    settings = {key: plain(values[key]) for key in swept if key in values}
    info = read_run_json(run_dir) if (run_dir / "run.json").is_file() else {}
    evaluations = read_evaluations(run_dir)
    best_episode = info.get("best_episode") if info.get("status") == "finished" else None
    if best_episode is None and evaluations:  # not finished: run.json lags behind; the first best, as training keeps it
        best_episode = int(max(evaluations, key=lambda r: float(r["delivered_fill"]))["episode"])
    row = next((r for r in evaluations if int(r["episode"]) == best_episode), None)
    episodes = _csv_rows(run_dir / "episodes.csv")  # one row per training episode, with the run's clock
    if error:
        status = "error"
    elif not info:
        status = "not started"
    elif info.get("status") == "finished":
        status = "finished"
    else:
        status = "stopped early"
    return TrialRow(trial_id=trial_id, settings=settings, seed=int(plain(params.get("seed", 0))),
                    score=float(row["delivered_fill"]) if row else math.nan,
                    fill_factor=float(row["fill_factor"]) if row else math.nan,
                    success=float(row["success"]) if row else math.nan,
                    best_episode=best_episode if row else None, episodes_done=len(episodes),
                    wall_s=round(max(float(info.get("wall_s", 0.0)), float(episodes[-1]["wall_s"]) if episodes else 0.0), 1),
                    status=status, run_dir=run_dir, error=error)


def ranked(rows: list[TrialRow]) -> list[TrialRow]:
    """Best score first (trials without one last), ties by trial id."""
    return sorted(rows, key=lambda r: (math.isnan(r.score), -r.score if not math.isnan(r.score) else 0.0, r.trial_id))


def export_best(row: TrialRow, path: Path, sweep: dict[str, Any]) -> Path | None:
    """Write the trial's kept policy (``RUN_DIR/policy.safetensors``) to ``path`` and its JSON sidecar, the
    format of ``autoscoop/policies/default.*`` (``autoscoop eval --policy PATH`` loads it), its metadata
    with the trial's (``sweep_*``: trial, settings, seed, score, the sweep's ``sweep``). ``None`` (nothing
    written) where the run has no safe actor file (PPO keeps ``policy.zip`` only)."""
    source = row.run_dir / "policy.safetensors"
    if not source.is_file():
        return None
    actor, meta = load_actor(source)  # checks the hash
    kept = {k: v for k, v in meta.items() if k not in ("format", "layers", "output", "sha256")}
    return save_actor(actor, path, {**kept, "sweep_trial": row.trial_id, "sweep_settings": row.settings,
                                    "sweep_seed": row.seed, "sweep_score_delivered_fill": row.score,
                                    "sweep_run_dir": str(row.run_dir), **{f"sweep_{k}": v for k, v in sweep.items()}})
