/**
  millpost post processor for Autodesk Fusion (and other Autodesk CAM products using .cps posts).

  Writes LinuxCNC/Fanuc-style G-code for 3-axis milling (G17/G18/G19 arcs with IJK centres,
  tool changes "T M6 G43 H", canned cycles expanded into G0/G1 by the post engine), then, once
  the NC file is closed (onTerminate), writes <name>.job.toml next to it (stock box from the
  setup's workpiece, tools from the tool table) and runs
      millpost optimize <name>.job.toml -o <name>.<ext>
  on a copy of the posted program (<name>.posted.<ext>). If millpost is missing or fails, the
  NC file is left exactly as posted and a warning says why: the user's output is never lost.

  Post API used (Autodesk CAM post processor reference, cam.autodesk.com/posts/reference, and the
  structure of Autodesk's generic posts, e.g. the "XYZ", "Dumper" and milling posts):
    header variables  description, vendor, capabilities, extension, tolerance, properties,
                      minimumChordLength, minimumCircularRadius, maximumCircularRadius,
                      minimumCircularSweep, maximumCircularSweep, allowHelicalMoves
    formatting        createFormat, createVariable, createModal, createReferenceVariable
                      (I/J/K = centre minus start), writeWords, writeln, getProperty
    entry functions   onOpen, onComment, onSection, onSpindleSpeed, onDwell, onRapid, onLinear,
                      onCircular (getCircularPlane, getCurrentPosition, linearize), onCyclePoint
                      (expandCyclePoint), onCommand, onRadiusCompensation, onSectionEnd, onClose,
                      onTerminate (called after the output file is closed)
    job data          getWorkpiece() (BoundingBox .lower/.upper), getToolTable() (getNumberOfTools,
                      getTool), tool.number/.diameter/.numberOfFlutes/.type/.cornerRadius/
                      .fluteLength/.bodyLength, getOutputPath(), FileSystem.getFolderPath/
                      getFilename/getCombinedPath/copyFile, TextFile, execute(path, arguments, hide,
                      workingFolder) returning the exit code.
*/

description = "millpost (LinuxCNC/Fanuc G-code, feeds optimised by millpost)";
vendor = "millpost";
vendorUrl = "https://github.com/millpost/millpost";
legal = "MIT License";
certificationLevel = 2;
minimumRevision = 45702;

longDescription = "3-axis milling post writing LinuxCNC/Fanuc-style G-code, then running 'millpost optimize' " +
  "to reschedule the feeds from cutting physics. Keeps the plain program when millpost is unavailable.";

extension = "nc";
setCodePage("ascii");

capabilities = CAPABILITY_MILLING;
tolerance = spatial(0.002, MM);

minimumChordLength = spatial(0.25, MM);
minimumCircularRadius = spatial(0.01, MM);
maximumCircularRadius = spatial(1000, MM);
minimumCircularSweep = toRad(0.01);
maximumCircularSweep = toRad(180);
allowHelicalMoves = true;
allowedCircularPlanes = undefined; // XY, ZX and YZ arcs are all output

properties = {
  millpostEnable: {
    title: "Optimise with millpost", description: "Run 'millpost optimize' on the posted program.",
    group: "millpost", type: "boolean", value: true, scope: "post"
  },
  millpostPath: {
    title: "millpost executable", description: "Full path of the millpost executable (millpost.exe on Windows).",
    group: "millpost", type: "string", value: "millpost", scope: "post"
  },
  millpostMaterial: {
    title: "Material", description: "millpost material: built-in name or TOML file.",
    group: "millpost", type: "string", value: "al6061", scope: "post"
  },
  millpostMachine: {
    title: "Machine", description: "millpost machine: built-in name or TOML file.",
    group: "millpost", type: "string", value: "benchtop-belt", scope: "post"
  }
};

var gFormat = createFormat({prefix: "G", decimals: 0});
var mFormat = createFormat({prefix: "M", decimals: 0});
var hFormat = createFormat({prefix: "H", decimals: 0});
var xyzFormat = createFormat({decimals: (unit == MM ? 4 : 5), forceDecimal: true});
var feedFormat = createFormat({decimals: (unit == MM ? 1 : 2), forceDecimal: true});
var rpmFormat = createFormat({decimals: 0});
var secFormat = createFormat({decimals: 3, forceDecimal: true});
var toolFormat = createFormat({decimals: 0});

var xOutput = createVariable({prefix: "X"}, xyzFormat);
var yOutput = createVariable({prefix: "Y"}, xyzFormat);
var zOutput = createVariable({prefix: "Z"}, xyzFormat);
var feedOutput = createVariable({prefix: "F"}, feedFormat);
var sOutput = createVariable({prefix: "S", force: true}, rpmFormat);
var iOutput = createReferenceVariable({prefix: "I", force: true}, xyzFormat);
var jOutput = createReferenceVariable({prefix: "J", force: true}, xyzFormat);
var kOutput = createReferenceVariable({prefix: "K", force: true}, xyzFormat);

var gMotionModal = createModal({}, gFormat); // G0-G3
var gPlaneModal = createModal({onchange: function () { gMotionModal.reset(); }}, gFormat); // G17-G19
var gAbsIncModal = createModal({}, gFormat); // G90-G91
var gUnitModal = createModal({}, gFormat); // G20-G21

var MM_PER_UNIT = (unit == IN) ? 25.4 : 1; // the post engine reports lengths in the output unit

function writeBlock() {
  writeWords(arguments);
}

function formatComment(text) {
  return "(" + String(text).replace(/[()]/g, "") + ")";
}

function writeComment(text) {
  writeln(formatComment(text));
}

function forceXYZ() {
  xOutput.reset();
  yOutput.reset();
  zOutput.reset();
}

function forceAny() {
  forceXYZ();
  feedOutput.reset();
  gMotionModal.reset();
}

function onOpen() {
  if (programName) {
    writeComment(programName);
  }
  if (programComment) {
    writeComment(programComment);
  }
  var tools = getToolTable();
  for (var i = 0; i < tools.getNumberOfTools(); ++i) {
    var t = tools.getTool(i);
    writeComment("T" + toolFormat.format(t.number) + " D=" + xyzFormat.format(t.diameter) +
      " CR=" + xyzFormat.format(t.cornerRadius) + " flutes=" + t.numberOfFlutes);
  }
  writeBlock(gAbsIncModal.format(90), gFormat.format(94), gPlaneModal.format(17), gFormat.format(40),
    gFormat.format(49), gFormat.format(80));
  writeBlock(gUnitModal.format(unit == MM ? 21 : 20));
}

function onComment(message) {
  writeComment(message);
}

var currentWorkOffset;

function onSection() {
  var remaining = currentSection.workPlane;
  if (!isSameDirection(remaining.forward, new Vector(0, 0, 1))) {
    error(localize("millpost post: only 3-axis work planes (tool along +Z) are supported."));
    return;
  }
  setRotation(remaining);

  var newTool = isFirstSection() || (tool.number != getPreviousSection().getTool().number);
  writeln("");
  if (hasParameter("operation-comment")) {
    writeComment(getParameter("operation-comment"));
  }
  if (newTool) {
    if (!isFirstSection()) {
      writeBlock(mFormat.format(9));
    }
    writeBlock(mFormat.format(5));
    writeBlock("T" + toolFormat.format(tool.number), mFormat.format(6));
    writeBlock(gFormat.format(43), hFormat.format(tool.lengthOffset || tool.number));
  }
  var workOffset = currentSection.workOffset || 1;
  if (workOffset > 6) {
    error(localize("millpost post: work offsets above 6 (G59) are not supported."));
    return;
  }
  if (workOffset != currentWorkOffset) {
    writeBlock(gFormat.format(53 + workOffset)); // G54-G59
    currentWorkOffset = workOffset;
  }
  forceAny();
  if (newTool || isSpindleSpeedDifferent()) {
    writeBlock(sOutput.format(spindleSpeed), mFormat.format(tool.clockwise ? 3 : 4));
  }
  if (tool.coolant == COOLANT_FLOOD) {
    writeBlock(mFormat.format(8));
  } else if (tool.coolant == COOLANT_MIST) {
    writeBlock(mFormat.format(7));
  }

  var initial = getFramePosition(currentSection.getInitialPosition());
  var current = getCurrentPosition();
  if (!newTool && current && initial.z > current.z) { // climb first, then travel
    writeBlock(gMotionModal.format(0), zOutput.format(initial.z));
    writeBlock(gMotionModal.format(0), xOutput.format(initial.x), yOutput.format(initial.y));
  } else {
    writeBlock(gMotionModal.format(0), xOutput.format(initial.x), yOutput.format(initial.y));
    writeBlock(gMotionModal.format(0), zOutput.format(initial.z));
  }
}

function isSpindleSpeedDifferent() {
  return getPreviousSection().getTool().spindleRPM != tool.spindleRPM ||
    getPreviousSection().getTool().clockwise != tool.clockwise;
}

function onSpindleSpeed(speed) {
  writeBlock(sOutput.format(speed));
}

function onDwell(seconds) {
  writeBlock(gFormat.format(4), "P" + secFormat.format(seconds));
}

function onRadiusCompensation() {
  if (radiusCompensation != RADIUS_COMPENSATION_OFF) {
    error(localize("millpost post: set the operation's compensation type to 'In computer' " +
      "(millpost steps the programmed tool centre, G41/G42 are not written)."));
  }
}

function onRapid(_x, _y, _z) {
  var x = xOutput.format(_x);
  var y = yOutput.format(_y);
  var z = zOutput.format(_z);
  if (x || y || z) {
    writeBlock(gMotionModal.format(0), x, y, z);
    feedOutput.reset();
  }
}

function onLinear(_x, _y, _z, feed) {
  var x = xOutput.format(_x);
  var y = yOutput.format(_y);
  var z = zOutput.format(_z);
  var f = feedOutput.format(feed);
  if (x || y || z) {
    writeBlock(gMotionModal.format(1), x, y, z, f);
  } else if (f) {
    feedOutput.reset(); // a zero-length move: keep the feed for the next block
  }
}

function onCircular(clockwise, cx, cy, cz, x, y, z, feed) {
  var start = getCurrentPosition();
  var g = gMotionModal.format(clockwise ? 2 : 3);
  switch (getCircularPlane()) {
  case PLANE_XY:
    writeBlock(gPlaneModal.format(17), g, xOutput.format(x), yOutput.format(y), zOutput.format(z),
      iOutput.format(cx, start.x), jOutput.format(cy, start.y), feedOutput.format(feed));
    break;
  case PLANE_ZX:
    writeBlock(gPlaneModal.format(18), g, xOutput.format(x), yOutput.format(y), zOutput.format(z),
      iOutput.format(cx, start.x), kOutput.format(cz, start.z), feedOutput.format(feed));
    break;
  case PLANE_YZ:
    writeBlock(gPlaneModal.format(19), g, xOutput.format(x), yOutput.format(y), zOutput.format(z),
      jOutput.format(cy, start.y), kOutput.format(cz, start.z), feedOutput.format(feed));
    break;
  default:
    linearize(tolerance); // arcs in other planes come back as onLinear moves
  }
}

function onCyclePoint(x, y, z) {
  expandCyclePoint(x, y, z); // drilling cycles as G0/G1 moves through onRapid/onLinear/onDwell
}

var mCommands = {};
mCommands[COMMAND_STOP] = 0;
mCommands[COMMAND_OPTIONAL_STOP] = 1;
mCommands[COMMAND_SPINDLE_CLOCKWISE] = 3;
mCommands[COMMAND_SPINDLE_COUNTERCLOCKWISE] = 4;
mCommands[COMMAND_STOP_SPINDLE] = 5;
mCommands[COMMAND_COOLANT_ON] = 8;
mCommands[COMMAND_COOLANT_OFF] = 9;

function onCommand(command) {
  if (command == COMMAND_START_SPINDLE) {
    writeBlock(mFormat.format(tool.clockwise ? 3 : 4));
  } else if (command in mCommands) {
    writeBlock(mFormat.format(mCommands[command]));
  } else if (command != COMMAND_END && command != COMMAND_LOAD_TOOL) {
    onUnsupportedCommand(command);
  }
}

function onSectionEnd() {
  forceAny();
}

function onClose() {
  writeln("");
  writeBlock(mFormat.format(9));
  writeBlock(mFormat.format(5));
  writeBlock(mFormat.format(30));
}

// --- millpost hand-off ---------------------------------------------------------------------------

var MILLPOST_SHAPES = {}; // Fusion tool type -> job.toml shape; other types are left to millpost
MILLPOST_SHAPES[TOOL_MILLING_END_FLAT] = "flat";
MILLPOST_SHAPES[TOOL_MILLING_FACE] = "flat";
MILLPOST_SHAPES[TOOL_MILLING_END_BALL] = "ball";
MILLPOST_SHAPES[TOOL_MILLING_END_BULLNOSE] = "bull";
MILLPOST_SHAPES[TOOL_MILLING_CHAMFER] = "chamfer";

function tomlString(text) {
  return JSON.stringify(String(text)); // a JSON string is a valid TOML basic string
}

function tomlNumber(x) {
  var s = String(Number(Number(x).toFixed(6)));
  return (/^-?\d+$/).test(s) ? s + ".0" : s;
}

/** job.toml text (docs/job-files.md): box = [[xmin,ymin,zmin],[xmax,ymax,zmax]] mm, tools in mm. */
function millpostJobToml(program, output, box, tools, material, machine) {
  var lines = [
    "# written by the millpost Fusion post",
    "program = " + tomlString(program),
    "output = " + tomlString(output),
    "dialect = \"linuxcnc\"",
    "material = " + tomlString(material),
    "machine = " + tomlString(machine),
    "",
    "[stock]",
    "box = [[" + box[0].map(tomlNumber).join(", ") + "], [" + box[1].map(tomlNumber).join(", ") + "]]"
  ];
  for (var i = 0; i < tools.length; ++i) {
    var t = tools[i];
    lines.push("", "[tools." + t.number + "]", "diameter_mm = " + tomlNumber(t.diameter_mm),
      "shape = " + tomlString(t.shape), "flutes = " + t.flutes,
      "corner_radius_mm = " + tomlNumber(t.corner_radius_mm));
    if (t.flute_length_mm > 0) {
      lines.push("flute_length_mm = " + tomlNumber(t.flute_length_mm));
    }
    if (t.stickout_mm > 0) {
      lines.push("stickout_mm = " + tomlNumber(t.stickout_mm));
    }
  }
  return lines.join("\n") + "\n";
}

/** Tools of the tool table in mm; tools millpost cannot model are reported, not written. */
function millpostTools() {
  var out = [];
  var seen = {};
  var table = getToolTable();
  for (var i = 0; i < table.getNumberOfTools(); ++i) {
    var t = table.getTool(i);
    if (seen[t.number]) {
      continue;
    }
    seen[t.number] = true;
    var shape = MILLPOST_SHAPES[t.type];
    if (shape === undefined) {
      warning("millpost: T" + t.number + " (" + getToolTypeName(t.type) + ") is not a tool millpost models; " +
        "millpost decides how to treat its moves.");
      continue;
    }
    out.push({
      number: t.number,
      diameter_mm: t.diameter * MM_PER_UNIT,
      shape: shape,
      flutes: t.numberOfFlutes,
      corner_radius_mm: (shape == "ball") ? t.diameter * MM_PER_UNIT / 2 : t.cornerRadius * MM_PER_UNIT,
      flute_length_mm: t.fluteLength * MM_PER_UNIT,
      stickout_mm: t.bodyLength * MM_PER_UNIT
    });
  }
  return out;
}

function onTerminate() {
  if (!getProperty("millpostEnable")) {
    return;
  }
  var outputPath = getOutputPath();
  var folder = FileSystem.getFolderPath(outputPath);
  var name = FileSystem.getFilename(outputPath);
  var dot = name.lastIndexOf(".");
  var stem = (dot > 0) ? name.substr(0, dot) : name;
  var ext = (dot > 0) ? name.substr(dot) : "";
  var postedName = stem + ".posted" + ext;
  var jobPath = FileSystem.getCombinedPath(folder, stem + ".job.toml");
  try {
    var workpiece = getWorkpiece();
    var box = [
      [workpiece.lower.x * MM_PER_UNIT, workpiece.lower.y * MM_PER_UNIT, workpiece.lower.z * MM_PER_UNIT],
      [workpiece.upper.x * MM_PER_UNIT, workpiece.upper.y * MM_PER_UNIT, workpiece.upper.z * MM_PER_UNIT]
    ];
    if (!(box[1][0] > box[0][0] && box[1][1] > box[0][1] && box[1][2] > box[0][2])) {
      warning("millpost: the setup has no stock box; kept the program as posted.");
      return;
    }
    FileSystem.copyFile(outputPath, FileSystem.getCombinedPath(folder, postedName));
    var file = new TextFile(jobPath, true, "ansi");
    file.write(millpostJobToml(postedName, name, box, millpostTools(),
      getProperty("millpostMaterial"), getProperty("millpostMachine")));
    file.close();
    // millpost writes the output atomically: on any failure the posted NC file is untouched.
    var args = "optimize \"" + jobPath + "\" -o \"" + outputPath + "\"";
    var code = execute(getProperty("millpostPath"), args, true, folder);
    if (code != 0) {
      warning("millpost: 'millpost optimize' exited with " + code + "; kept the program as posted. Job: " + jobPath);
    }
  } catch (e) {
    warning("millpost: could not run millpost (" + e + "); kept the program as posted. Job: " + jobPath);
  }
}
