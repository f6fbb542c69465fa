"""Running a policy on the robot: the controller's logic (ROS-free), ONNX export, ROS front ends.

The ONNX runner the robot loads lives with the other policy files, :mod:`autoscoop.agents.onnx_policy`.

* :mod:`autoscoop.deploy.robot_config`: the robot's YAML (limits, timeouts, potentiometer calibration,
  topic names), validated at start-up.
* :mod:`autoscoop.deploy.safety`: input watchdog and command limiter, pure classes with an injectable clock.
* :mod:`autoscoop.deploy.controller`: the controller node's logic; it builds the state with
  :func:`autoscoop.core.state.build_state` and moves targets with :func:`autoscoop.core.state.advance_targets`.
* :mod:`autoscoop.deploy.sim_bridge`: the simulator behind the robot's topics (ROS-free part).
* :mod:`autoscoop.deploy.export`: torch actor -> ONNX, with a parity check.
* :mod:`autoscoop.deploy.ros1`: the rospy front ends; the only modules here that import ROS.
"""
