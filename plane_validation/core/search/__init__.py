"""Plane search, one module per step, in the order the data flows:

* :mod:`.checks`: arguments and points validated at the edge (nothing below sees unchecked input);
* :mod:`.detect`: :func:`~.detect.detect_planes`, which runs one of two searches:
  * :mod:`.infinite`: the paper's infinite planes (``connectivity=False``);
  * :mod:`.connected`: connected planar regions over a :mod:`.graph` (:class:`~.graph.SearchGraph`: the searched
    points, on an image's :mod:`.grid` or a sample of an unorganized cloud, and their neighbourhood: one
    interface, :class:`~.neighbours.Neighbours`, in two forms, :mod:`.neighbours_grid` (built by :mod:`.grid_build`)
    and :mod:`.neighbours_graph`, chosen once when the graph is built);
* :mod:`.sequential`: both searches take planes one by one, each from a RANSAC run (:mod:`.hypotheses`) with
  least-squares fits (:mod:`.fit`);
* :mod:`.types`: the results (:class:`~.types.Plane`, :class:`~.types.Segmentation`); :mod:`.carry`: labels
  carried to other points.

Every compiled kernel is in :mod:`..kernels`. :mod:`..ransac` names the public entry points.
"""
