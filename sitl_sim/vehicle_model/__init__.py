"""The simulated airframes: 6-DOF rigid-body dynamics with motors, drag, wind and ground contact, the attitude
controller running at the physics rate (one compiled implementation: attitude_control.py's kernels inside
dynamics.advance), and the position-control laws the autopilot's outer loop calls. World ENU, body FLU, SI
units. Imports nothing else of sitl_sim."""
