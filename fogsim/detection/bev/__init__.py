"""The cross-density study on LiDAR and radar: bird's-eye-view (BEV) rasters of each fog level's scans
and radar detections, rotated boxes from the 3D labels, one oriented-box detector per level plus a mixed
one, scored by BEV AP and recall per distance (``fogsim study --sensor lidar|lidar+radar``,
``docs/study.md``)"""
