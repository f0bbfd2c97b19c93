"""Map compression ([SSLAM] III-A-4): the optimised drives become a graph of places with reference frames.

Modules: ``adjacency`` (nodes traced along the drives and their graph), ``distances`` (path lengths and
HMM transitions on that graph), ``model`` (the :class:`~driftmap.core.topomap.model.TopoMap` and its
parameters), ``build`` (building it) and ``database`` (which frames each node keeps; [SESAME] 3.4-3.5).
"""
