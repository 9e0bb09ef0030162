"""fogsim's on-disk dataset format, one owner: :mod:`~fogsim.dataset.layout` (every path and
reserved name), :mod:`~fogsim.dataset.coco` (the COCO record: categories, annotations, the
per-level file), :mod:`~fogsim.dataset.writer` (labels, COCO files, split lists and the split
rule, data files, manifest) and :mod:`~fogsim.dataset.reader` (what every consumer — the study,
the depth benchmark — reads). Producers (renderer, ``fogsim fog``) write through the writer."""
