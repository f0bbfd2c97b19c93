"""Online localisation against a stored map ([SSLAM] III-B): one frame in, one position estimate out.

Modules: ``hmm`` (node scores, transitions, the HMM update; eq. 4-10), ``map`` (the map a localiser
runs on), ``localiser`` (the per-frame step), ``state`` (what it reports and keeps), ``motion`` (the
vehicle's own odometry), ``track`` (the continuous position along the tunnels) and ``camera_check``
(is the camera obscured?).
"""
