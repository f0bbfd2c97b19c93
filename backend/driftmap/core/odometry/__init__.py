"""Ground-plane visual odometry ([SSLAM] III-A-1, eq. 1-2): a drive's steps from its camera frames.

Modules: ``params`` (parameters, presets), ``camera`` (the calibrated camera), ``grid`` (the matching
grid, linear or bird's-eye), ``step`` (one step between two frames), ``drive`` (a drive's steps,
self-calibration and dead reckoning), ``pitch`` (the slowly varying horizon), ``rotation_centre``
(the rotation-centre fit), ``ground_setup`` (the ground plane from clicked floor points or a board),
``birdseye`` (the floor around the ground ROI seen from above, to check a fit by eye) and ``scale_check`` (floor
scale and forward_sign from a measured straight drive).
"""
