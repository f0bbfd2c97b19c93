"""The pose graph of Semi-Supervised SLAM ([SSLAM] III-A-3): drives, loop closures and groundings solved.

Modules: ``alignment`` (SE(2) helpers and the rigid placement of dead-reckoned drives in the survey
frame), ``constraints`` (what the graph is made of and its parameters), ``posegraph`` (the GTSAM
session and solve) and ``drive_bias`` (each drive's odometry bias fitted to the optimised map).
"""
