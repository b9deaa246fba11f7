"""Motor operating regions: spec sheets, regions, transmissions, joint space, saturation.

Modules: :mod:`~hound_id.mor.spec` (spec sheets), :mod:`~hound_id.mor.region` (the MOR),
:mod:`~hound_id.mor.transmission` (gearbox matrices), :mod:`~hound_id.mor.robot` (robot
files), :mod:`~hound_id.mor.joint_space` (joint regions and URDF boxes),
:mod:`~hound_id.mor.saturation` (the training-time clip), :mod:`~hound_id.mor.plot`.
"""
