"""The live path: vehicles' frames in, positions out to the watchers, the localiser state in the database.

- :mod:`~driftmap.live.ingest`: :class:`~driftmap.live.ingest.LiveService`, the per-vehicle lanes that feed
  posted frames to the localiser in order and share each result.
- :mod:`~driftmap.live.workers`: the localiser worker processes the lanes hand frames to.
- :mod:`~driftmap.live.localise`: one frame of one vehicle localised and stored, the stored state's encoding.
- :mod:`~driftmap.live.start`: a vehicle's known start seeded as its stored localiser belief.
- :mod:`~driftmap.live.hub`: the push of positions to watchers (one process, or several through Redis).
- :mod:`~driftmap.live.latest_frames`: the newest localised frame of each vehicle (memory or Redis).

The HTTP and WebSocket routes are :mod:`driftmap.api.live`; the messages watchers get are the models of
:mod:`driftmap.api.schemas_live`.
"""
