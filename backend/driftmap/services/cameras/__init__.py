"""Cameras as a service: calibration (:mod:`.calibration`) and named camera profiles (:mod:`.profiles`).

The CLI (``driftmap camera``) and the API (``/api/cameras``, ``/api/camera-profiles``) call these alike.
"""
