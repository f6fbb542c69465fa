"""Training runs: the algorithm's settings (``hyperparams/``), run directories, callbacks, checkpoints."""
