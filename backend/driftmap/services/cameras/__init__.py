"""Cameras as a service: calibration (:mod:`.calibration`), previews of a camera in set-up (:mod:`.preview`) and
named camera profiles (:mod:`.profiles`).

The CLI (``driftmap camera``) and the API (``/api/cameras``, ``/api/camera-profiles``) call these alike.
"""
