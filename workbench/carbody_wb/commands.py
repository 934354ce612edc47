"""The workbench's toolbar commands: load photo, load keypoints, reconstruct, move junction,
preferences. Reconstruct runs ``carbody reconstruct`` in the background
(:class:`carbody_wb.core.ReconstructJob`): FreeCAD stays responsive, each stage shows in the
status bar and the report view."""
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

    job = None  # the run in progress (one at a time)

    def IsActive(self):
        return Reconstruct.job is None or not Reconstruct.job.running

    def run(self):
        from PySide import QtGui

        params = FreeCAD.ParamGet(core.PARAM_PATH)
        image, keypoints = params.GetString("LastImage", ""), params.GetString("LastKeypoints", "")
        if not image or not keypoints:
            raise core.CarbodyWorkbenchError("load a photo and its keypoints first")
        out = QtGui.QFileDialog.getExistingDirectory(None, "Output folder")
        if not out:
            return
        doc = _doc()

        def done(ok, result):
            Reconstruct.job = None
            if not ok:
                _status(f"carbody: {result}", error=True)
                return
            _status("carbody: bringing the car in ...")
            try:
                _, _, report = core.import_reconstruction(doc, image, out, **result)
            except core.CarbodyWorkbenchError as exc:
                _status(f"carbody: {exc}", error=True)
                return
            FreeCAD.Console.PrintMessage(core.summary(out))
            _status(f"carbody: done, the car is in {doc.Label}")
            _look_as_the_photo(report["fit"].get("photo_plane"))

        _status(f"carbody: reconstructing {image} into {out} (FreeCAD stays usable meanwhile) ...")
        Reconstruct.job = core.ReconstructJob(image, keypoints, out, on_progress=lambda t: _status(f"carbody: {t}"),
                                              on_done=done).start()


def _status(text, error=False):
    """A line in the status bar and the report view."""
    (FreeCAD.Console.PrintError if error else FreeCAD.Console.PrintMessage)(text + "\n")
    window = FreeCADGui.getMainWindow()
    if window is not None:
        window.statusBar().showMessage(text, 0 if error else 15000)


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

        stored = FreeCAD.ParamGet(core.PARAM_PATH).GetString("CarbodyCommand", "")
        found = " ".join(core.carbody_command())
        text, ok = QtGui.QInputDialog.getText(None, "carbody", "carbody command (empty: the one in the "
                                              f"workbench's venv or on PATH, now {found}):", text=stored)
        if ok:
            core.set_carbody_command(text.strip())


def register():
    """Add the commands to FreeCAD; returns their names in toolbar order."""
    commands = {"Carbody_LoadPhoto": LoadPhoto(), "Carbody_LoadKeypoints": LoadKeypoints(),
                "Carbody_Reconstruct": Reconstruct(), "Carbody_MoveJunction": MoveJunction(),
                "Carbody_Preferences": Preferences()}
    for name, command in commands.items():
        FreeCADGui.addCommand(name, command)
    return list(commands)
