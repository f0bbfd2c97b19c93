"""Appearance-only loop closure between keyframes ([SSLAM] III-A-2, eq. 3).

Modules: ``params`` (parameters, presets), ``descriptors`` (coarse descriptors and candidates),
``pair_scores`` (eq. 3 on pairs and along diagonals), ``blocks`` (the search planned once and scored
in independent query blocks) and ``search`` (the sequential decisions and the whole search).
"""
