"""Place recognition on outside datasets: single-image matching, the route HMM, and the metrics.

Modules: ``single`` (SAD / SESAME matching of one query image), ``route`` (the HMM of [SSLAM] over a
route of reference images), ``route_filter`` (its forward filter and smoother) and ``metrics``
(recall@1, precision-recall, calibration).
"""
