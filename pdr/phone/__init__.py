"""The phone pipeline: a phone's inertial, magnetic and pressure samples in, a step-wise PDR track out.

Modules, in the order of the data flow (:mod:`~pdr.phone.pipeline` composes them, online, batch by batch):
:mod:`~pdr.phone.grid` (sensors on one uniform grid) and :mod:`~pdr.phone.magcal` (online hard-iron offset),
:mod:`~pdr.phone.attitude` (quaternion UKF of seed 003, EKF baseline), :mod:`~pdr.phone.steps` (step detector,
seed 004), :mod:`~pdr.phone.step_length` (step patterns and length), :mod:`~pdr.phone.heading` (device heading,
improved RMPCA and its second UKF, drift elimination), :mod:`~pdr.phone.gyro_yaw` (gyro yaw of a device axis),
:mod:`~pdr.phone.landmarks` (landmark labels, elevator rides, the site description), :mod:`~pdr.phone.floors`
(barometric floors) and :mod:`~pdr.phone.track` (PDR mechanisation); offline,
:mod:`~pdr.phone.heading_smoother` smooths a finished walk's step headings.
"""
