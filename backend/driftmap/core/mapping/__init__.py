"""The Semi-Supervised SLAM mapping pipeline ([SSLAM] III-A): drives in, an optimised topological map out.

Modules: ``drive`` (one drive's odometry, thumbnails and frame statistics, in segments), ``prepare``
(stages 1-3: odometry, keyframes, loop-closure search; the parameters and presets) and ``pipeline``
(the pose graph, groundings and map compression).
"""
