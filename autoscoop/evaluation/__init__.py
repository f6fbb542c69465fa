"""Measuring controllers: evaluation over seeds, summary statistics, episode recorder, video, speed
and payload benchmarks, manual control."""
