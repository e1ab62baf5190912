"""Opens coif's .usda exports in Blender and checks what arrived (run by scripts/blender-check.sh).

Usage: python blender_usda_check.py FILE.usda CURVES POINTS
Imports the file with Blender's own USD importer into an empty scene and checks the curve
count and the point count of the first frame; for an animated export (an endTimeCode in the
file), that Blender's frame range is the file's and the curves move between the first and
the last frame. Exits 1 with the reason.
"""
import re
import sys

import bpy
import numpy as np

path, curves, points = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
end = re.search(r"endTimeCode = (\d+)", open(path).read())
end = int(end.group(1)) if end else None

bpy.ops.wm.read_factory_settings(use_empty=True)
result = bpy.ops.wm.usd_import(filepath=path)
if result != {"FINISHED"}:
    sys.exit(f"{path}: Blender's USD import returned {result}")

hair = [o for o in bpy.context.scene.objects if o.type in ("CURVES", "CURVE")]
if len(hair) != 1:
    kinds = [(o.name, o.type) for o in bpy.context.scene.objects]
    sys.exit(f"{path}: expected one curves object, Blender made {kinds}")
obj = hair[0]


def counts(o):
    """(curves, points, positions) of the evaluated object at the current frame."""
    ev = o.evaluated_get(bpy.context.evaluated_depsgraph_get())
    if o.type != "CURVES":
        sys.exit(f"{path}: Blender made a legacy {o.type} object, not hair curves")
    pos = np.empty(len(ev.data.points) * 3, dtype=np.float32)
    ev.data.attributes["position"].data.foreach_get("vector", pos)
    return len(ev.data.curves), len(ev.data.points), pos


bpy.context.scene.frame_set(bpy.context.scene.frame_start)
n_curves, n_points, first = counts(obj)
print(f"blender {bpy.app.version_string}: {path}: object {obj.name!r} ({obj.type}), "
      f"{n_curves} curves, {n_points} points; coif wrote {curves} curves, {points} points")
if (n_curves, n_points) != (curves, points):
    sys.exit(f"{path}: Blender read {n_curves} curves and {n_points} points, coif wrote {curves} and {points}")

if end is not None:
    scene = bpy.context.scene
    print(f"frame range {scene.frame_start}..{scene.frame_end}; the file's 0..{end}")
    if (scene.frame_start, scene.frame_end) != (0, end):
        sys.exit(f"{path}: Blender's frame range is not the file's 0..{end}")
    scene.frame_set(end)
    _, _, last = counts(obj)
    moved = float(np.abs(last - first).max())
    print(f"largest move of a point between the first and last frame: {moved:.3g} (file units)")
    if moved == 0.0:
        sys.exit(f"{path}: the animated export does not move in Blender")
print("ok")
