"""Run inside FreeCAD 0.20's `freecadcmd` (Path workbench, no GUI) by tests/test_freecad_real.py.

Builds a part (a 40 × 30 × 10 mm block with a 20 × 12 × 4 mm pocket), a Job on it with an Adaptive and a
Pocket operation, then posts it twice through FreeCAD's own post machinery (PostProcessor.load of the
`millpost` post found on the macro path): once with --inches and no optimization, once optimized in mm.
Settings come from the environment (MILLPOST_FC_*); results are written as JSON to MILLPOST_FC_RESULT.
"""

import json
import os
import traceback

import FreeCAD

out_dir = os.environ["MILLPOST_FC_OUT"]
result = {"ok": False}
try:
    import Part
    FreeCAD.ParamGet("User parameter:BaseApp/Preferences/Macro").SetString("MacroPath", os.environ["MILLPOST_FC_POSTS"])
    from PathScripts import PathAdaptive, PathJob, PathPocketShape
    from PathScripts.PathPostProcessor import PostProcessor

    doc = FreeCAD.newDocument("millpost")
    block = Part.makeBox(40, 30, 10)
    recess = Part.makeBox(20, 12, 4, FreeCAD.Vector(10, 9, 6))
    part = doc.addObject("Part::Feature", "Part")
    part.Shape = block.cut(recess)
    doc.recompute()
    floor = next(f"Face{i + 1}" for i, f in enumerate(part.Shape.Faces)
                 if abs(f.Surface.Axis.z) > 0.999 and abs(f.CenterOfMass.z - 6) < 1e-6)
    job = PathJob.Create("Job", [part])
    doc.recompute()
    tc = job.Tools.Group[0]
    tc.Tool.Diameter = 6.0
    tc.SpindleSpeed = 12000
    tc.HorizFeed = FreeCAD.Units.Quantity("900 mm/min")
    tc.VertFeed = FreeCAD.Units.Quantity("200 mm/min")
    model = job.Model.Group[0]
    adaptive = PathAdaptive.Create("Adaptive", parentJob=job)
    adaptive.Base = [(model, [floor])]
    adaptive.ToolController = tc
    adaptive.StepOver = 20
    adaptive.StepDown = 2
    pocket = PathPocketShape.Create("Pocket", parentJob=job)
    pocket.Base = [(model, [floor])]
    pocket.ToolController = tc
    pocket.StepDown = 2
    doc.recompute()
    result["moves"] = {op.Name: len(op.Path.Commands) for op in (adaptive, pocket)}
    objects = [tc, adaptive, pocket]
    posts = []
    for name, args in (("inch", "--no-show-editor --inches --no-optimize"),
                       ("mm", "--no-show-editor --material al6061 --machine vmc-small --timeout 900 --millpost "
                              + os.environ["MILLPOST_FC_EXE"])):
        target = os.path.join(out_dir, f"{name}.ngc")
        processor = PostProcessor.load("millpost")
        gcode = processor.export(objects, target, args)
        posts.append({"name": name, "file": target, "returned_equals_file": gcode == open(target).read()})
    result.update(ok=True, posts=posts, stock=[job.Stock.Shape.BoundBox.XMin, job.Stock.Shape.BoundBox.ZMax])
except Exception:
    result["error"] = traceback.format_exc()
with open(os.environ["MILLPOST_FC_RESULT"], "w") as fh:
    json.dump(result, fh)
