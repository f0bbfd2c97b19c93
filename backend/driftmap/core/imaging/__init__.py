"""Image pre-processing, the shifted SAD and shift registration: the image operations every stage shares.

Modules: ``params`` (image and SAD parameters, presets), ``images`` (gray, crop, down-sample, patch
normalisation; [SSLAM] IV-C), ``sad`` (shifted sum of absolute differences, masked; [SSLAM] eq. 3/4,
[SESAME] eq. 6), ``registration`` (sub-pixel shift between two images by coarse-to-fine masked SAD) and
``shift_cost`` (its two-sided cost), ``lens`` (lens models and undistortion tables), ``views`` (a camera's
thumbnail view: frames undistorted to one pinhole view before place recognition) and ``calibration`` (lens
intrinsics from chessboard views).
"""
