"""Registers the carbody workbench with FreeCAD's GUI."""
import os

import FreeCADGui


class CarbodyWorkbench(FreeCADGui.Workbench):
    """Photo + keypoints -> car body: load a photo, load keypoints, reconstruct."""

    MenuText = "carbody"
    ToolTip = "Reconstruct an editable car body from one photo and its keypoints"

    def __init__(self):
        import carbody_wb

        self.__class__.Icon = os.path.join(carbody_wb.ICONS, "carbody.svg")

    def Initialize(self):
        from carbody_wb import commands

        names = commands.register()
        self.appendToolbar("carbody", names)
        self.appendMenu("carbody", names)

    def GetClassName(self):
        return "Gui::PythonWorkbench"


FreeCADGui.addWorkbench(CarbodyWorkbench())
