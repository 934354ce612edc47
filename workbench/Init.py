# carbody workbench: nothing to do without the GUI (the macro and carbody_wb.core run headless).
