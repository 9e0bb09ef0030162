"""Object classes. Labelled classes get boxes; stuff classes only get instance ids."""

#: detection classes, in YOLO id order
LABELLED = ("car", "van", "truck", "bus", "pedestrian", "cyclist", "traffic_light", "traffic_sign")
#: scenery: in the instance mask (so occlusion is exact) but never boxed
STUFF = ("road", "lane_marking", "sidewalk", "curb", "building", "pole", "tree")

CLASS_ID = {name: i for i, name in enumerate(LABELLED)}


def is_labelled(cls: str) -> bool:
    return cls in CLASS_ID
