"""MuJoCo side of autoscoop: the scene builder with its public pose and observer API, the pile, the
load cell, the bucket's capacity, the off-screen OpenGL backend. Simulation only, no plotting.

Import the modules themselves (``autoscoop.sim.scene``): this package imports nothing, so that
``autoscoop.sim.glbackend`` can pick a backend before MuJoCo is first imported.
"""
