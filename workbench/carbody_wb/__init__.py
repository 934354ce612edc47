"""carbody FreeCAD workbench: GUI commands (``commands``) over a headless core (``core``)."""
import os

ICONS = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "Resources", "icons")
