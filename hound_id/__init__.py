"""hound-id: identify and design the actuators of fast legged robots.

Subpackages: :mod:`hound_id.mor` (operating regions, transmissions, saturation),
:mod:`hound_id.dyno`, :mod:`hound_id.foot`, :mod:`hound_id.export`.
Heavy libraries (torch, pinocchio, mujoco, matplotlib) are imported only by the
functions that need them.
"""

__version__ = "0.1.0"
