"""The workbench's toolbar commands: load photo, load keypoints, reconstruct, move junction,
preferences. Reconstruct runs ``carbody reconstruct`` in a QProcess: FreeCAD stays responsive,
the run's progress shows in the status bar and its messages in the report view."""
import os

import FreeCAD
import FreeCADGui

from carbody_wb import ICONS
from carbody_wb import core


def _ask_file(title, filters):
    from PySide import QtGui

    path, _ = QtGui.QFileDialog.getOpenFileName(None, title, "", filters)
    return path or None


def _doc():
    return FreeCAD.ActiveDocument or FreeCAD.newDocument("carbody")


class _Command:
    icon = "carbody.svg"
    menu = ""
    tooltip = ""

    def GetResources(self):
        return {"Pixmap": os.path.join(ICONS, self.icon), "MenuText": self.menu, "ToolTip": self.tooltip}

    def IsActive(self):
        return True

    def Activated(self):
        try:
            self.run()
        except core.CarbodyWorkbenchError as exc:
            FreeCAD.Console.PrintError(f"carbody: {exc}\n")


class LoadPhoto(_Command):
    icon = "load_photo.svg"
    menu = "Load car photo"
    tooltip = "Show a car photo as an image plane in the car's side plane"

    def run(self):
        path = _ask_file("Car photo", "Images (*.png *.jpg *.jpeg)")
        if path:
            core.add_photo(_doc(), path)
            FreeCAD.ParamGet(core.PARAM_PATH).SetString("LastImage", path)


class LoadKeypoints(_Command):
    icon = "load_keypoints.svg"
    menu = "Load keypoints"
    tooltip = "Choose the keypoints file of the photo (carbody JSON, COCO or labelme)"

    def run(self):
        path = _ask_file("Keypoints", "Keypoints (*.json)")
        if path:
            FreeCAD.ParamGet(core.PARAM_PATH).SetString("LastKeypoints", path)
            FreeCAD.Console.PrintMessage(f"carbody: keypoints {path}\n")


class Reconstruct(_Command):
    icon = "reconstruct.svg"
    menu = "Reconstruct car body"
    tooltip = ("Run carbody on the photo and keypoints (in the background); bring the car in as "
               "curves with editable poles and a body recomputed from them")
    process = None

    def IsActive(self):
        return self.process is None  # one run at a time

    def run(self):
        from PySide import QtCore, QtGui

        params = FreeCAD.ParamGet(core.PARAM_PATH)
        image, keypoints = params.GetString("LastImage", ""), params.GetString("LastKeypoints", "")
        if not image or not keypoints:
            raise core.CarbodyWorkbenchError("load a photo and its keypoints first")
        out = QtGui.QFileDialog.getExistingDirectory(None, "Output folder")
        if not out:
            return
        cmd = core.resolve_command()
        process = QtCore.QProcess()
        process.setProgram(cmd[0])
        process.setArguments([*cmd[1:], *core.reconstruct_args(image, keypoints, out)])
        self.process, self.doc, self.image, self.out, self.tail = process, _doc(), image, out, ""
        process.readyReadStandardError.connect(self._progress)
        process.readyReadStandardOutput.connect(self._output)
        process.finished.connect(self._finished)
        process.errorOccurred.connect(self._failed)
        _status("carbody: reconstructing ...")
        FreeCAD.Console.PrintMessage(f"carbody: reconstructing {image} into {out}\n")
        process.start()

    def _progress(self):
        """Progress bars redraw with a carriage return: the status bar shows the latest."""
        text = bytes(self.process.readAllStandardError()).decode(errors="replace")
        self.tail = (self.tail + text)[-4000:]
        pieces = [p.strip() for p in text.replace("\r", "\n").split("\n") if p.strip()]
        if pieces:
            _status(f"carbody: {pieces[-1]}")

    def _output(self):
        FreeCAD.Console.PrintMessage(bytes(self.process.readAllStandardOutput()).decode(errors="replace"))

    def _failed(self, error):
        from PySide import QtCore

        if error == QtCore.QProcess.FailedToStart:  # no finished() follows
            FreeCAD.Console.PrintError(f"carbody: could not start {self.process.program()!r}\n")
            self._reset()

    def _finished(self, code, _status_code=None):
        try:
            if code != 0:
                lines = [line for line in self.tail.replace("\r", "\n").splitlines() if line.strip()]
                raise core.CarbodyWorkbenchError(lines[-1] if lines else f"carbody exited with code {code}")
            _status("carbody: bringing the car in ...")
            _, _, report = core.import_reconstruction(self.doc, self.image, self.out)
            FreeCAD.Console.PrintMessage(core.summary(self.out))
            _look_as_the_photo(report["fit"].get("photo_plane"))
            _status("carbody: done")
        except core.CarbodyWorkbenchError as exc:
            FreeCAD.Console.PrintError(f"carbody: {exc}\n")
            _status("carbody: failed (see the report view)")
        finally:
            self._reset()

    def _reset(self):
        self.process = None  # IsActive again: the toolbar button comes back on its next update


def _status(text):
    FreeCADGui.getMainWindow().statusBar().showMessage(text)


class MoveJunction(_Command):
    icon = "carbody.svg"
    menu = "Move junction..."
    tooltip = ("Move the junction at the selected curve end by dx, dy, dz (mm): the curves meeting "
               "there and the mirror half follow; recompute to update the body")

    def run(self):
        from PySide import QtGui

        picked = [(s.Object, n) for s in FreeCADGui.Selection.getSelectionEx() for n in s.SubElementNames
                  if hasattr(s.Object, "CurveName") and n.startswith("Vertex")]
        if not picked:
            raise core.CarbodyWorkbenchError("select the end (a vertex) of a carbody curve first")
        obj, vertex = picked[0]
        junction = obj.StartJunction if vertex == "Vertex1" else obj.EndJunction
        text, ok = QtGui.QInputDialog.getText(None, "carbody", f"move {junction} by dx, dy, dz (mm):", text="0, 0, 50")
        if ok and text:
            from carbody_wb import model

            delta = [float(v) for v in text.replace(";", ",").split(",")]
            groups = [o for o in obj.InList if o.isDerivedFrom("App::DocumentObjectGroup")]
            model.move_junction(groups[0] if groups else obj.Document, junction, delta)
            obj.Document.recompute()


def _look_as_the_photo(placement):
    """Turn the 3D view to the fitted camera: the wireframe on the photo, as on the overlay."""
    view = FreeCADGui.ActiveDocument.ActiveView
    if placement is None:
        view.fitAll()
        return
    camera = core.photo_camera(placement)
    view.setCameraType("Orthographic" if camera["position"] is None else "Perspective")
    view.setCameraOrientation(camera["rotation"])
    view.fitAll()
    if camera["position"] is not None:
        node = view.getCameraNode()
        node.position.setValue(*camera["position"])
        node.heightAngle.setValue(camera["height_angle"])


class Preferences(_Command):
    icon = "carbody.svg"
    menu = "carbody command..."
    tooltip = "Set the path of the carbody command this workbench runs"

    def run(self):
        from PySide import QtGui

        text, ok = QtGui.QInputDialog.getText(None, "carbody", "carbody command:", text=" ".join(core.carbody_command()))
        if ok and text:
            core.set_carbody_command(text)


def register():
    """Add the commands to FreeCAD; returns their names in toolbar order."""
    commands = {"Carbody_LoadPhoto": LoadPhoto(), "Carbody_LoadKeypoints": LoadKeypoints(),
                "Carbody_Reconstruct": Reconstruct(), "Carbody_MoveJunction": MoveJunction(),
                "Carbody_Preferences": Preferences()}
    for name, command in commands.items():
        FreeCADGui.addCommand(name, command)
    return list(commands)
