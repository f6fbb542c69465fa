"""Training runs (``autoscoop train``), one job per module:

* :mod:`~autoscoop.training.recipes`: the recipes (``recipes/NAME.yaml``, inheriting through ``base``), the one
  list the CLI, the sweep and the docs read, and the worlds registered from them;
* :mod:`~autoscoop.training.settings`: the algorithm's YAML (``hyperparams/ALGO.yaml``) with a recipe laid over
  it, and ``--hyper`` overrides;
* :mod:`~autoscoop.training.factories`: the SB3 policy, the exploration noise, the vector environment;
* :mod:`~autoscoop.training.callbacks`: the per-episode log (``episodes.csv``) and the periodic evaluation;
* :mod:`~autoscoop.training.checkpoints`: checkpoints, safe actor files, ``run.json``, what resuming reads back;
* :mod:`~autoscoop.training.model_state`: a model's tensors, counters, noise and replay buffer without pickle;
* :mod:`~autoscoop.training.run`: :class:`~autoscoop.training.run.TrainArgs`, ``train`` and ``resume``;
* :mod:`~autoscoop.training.learning_curve`: the paper's Fig. 8 from ``episodes.csv``.
"""
