"""The task's definitions, numpy only: config schema, kinematics, state vector, reward, payload statics, phases.

Everything else (simulator, environment, agents, the ROS node, the exports) calls these; nothing
here imports MuJoCo, Gymnasium or torch.
"""
