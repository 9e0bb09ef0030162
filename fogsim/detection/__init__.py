"""The per-density detection study: YOLO training and prediction (``detection.yolo``, the only
module that imports Ultralytics), COCO evaluation, the cross-density table, fog-level
estimation and routing, and the study driver."""
