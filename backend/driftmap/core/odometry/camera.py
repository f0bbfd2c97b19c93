"""The calibrated camera of one drive, as the ground-plane odometry needs it.

The fields mirror the ``camera`` block of ``drive.json`` (``docs/formats.md``). The frame
used by ``ground_homography`` is the camera's look frame: x the way the camera looks (forward for ``forward_sign``
+1, backward for -1), y to its left, origin on the floor under the camera, metres. A camera
with a ``lens`` has its ROI, ``k_x``, ``k_y``, ``y_h`` and homography defined on the undistorted image
(:mod:`driftmap.core.imaging.lens`); odometry undistorts the region it needs before matching.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.lens import Lens
from driftmap.errors import BadInputError


@dataclass(frozen=True)
class CameraModel:
    """Intrinsic and mounting facts of a drive's camera.

    Attributes:
        width_px: width of the stored frames, pixels.
        height_px: height of the stored frames, pixels.
        ground_roi_px: (x, y, w, h) pixel rectangle lying on the floor, used by ground-plane VO.
        k_x_m_per_px: metres per pixel of image shift in x inside the ROI (paper eq. 1).
        k_y_m_per_px: metres per pixel of image shift in y inside the ROI (paper eq. 2).
        y_c_m: metres from the rear axle to the camera (eq. 1).
        y_h_m: metres from the camera to the floor point at the ROI centre (eq. 1).
        forward_sign: +1 when image content moves down (+v) as the vehicle drives forward, else -1.
        ground_homography: optional (3, 3) map from pixel (u, v, 1) to the floor point
            (x, y, w) in metres in the look frame at the camera's foot.
        lens: optional lens model; None for an ideal pinhole (frames used as recorded).
    """

    width_px: int
    height_px: int
    ground_roi_px: tuple[int, int, int, int]
    k_x_m_per_px: float
    k_y_m_per_px: float
    y_c_m: float
    y_h_m: float
    forward_sign: int = 1
    ground_homography: tuple[tuple[float, float, float], ...] | None = None
    lens: Lens | None = None

    def __post_init__(self) -> None:
        if self.width_px <= 0 or self.height_px <= 0:
            raise BadInputError("frame size must be positive", field="width_px")
        x, y, w, h = self.ground_roi_px
        if w <= 0 or h <= 0 or x < 0 or y < 0 or x + w > self.width_px or y + h > self.height_px:
            raise BadInputError(
                f"{self.ground_roi_px} does not fit a {self.width_px}x{self.height_px} frame",
                field="ground_roi",
            )
        if self.forward_sign not in (1, -1):
            raise BadInputError("must be +1 or -1", field="forward_sign")
        if self.ground_homography is not None and np.asarray(self.ground_homography).shape != (3, 3):
            raise BadInputError("must be 3x3", field="ground_homography")

    def homography(self) -> NDArray[np.float64] | None:
        """The ground homography as a (3, 3) float64 array, or None when the drive has none."""
        if self.ground_homography is None:
            return None
        return np.asarray(self.ground_homography, dtype=np.float64)
