"""The live 3-D view of the workcell (LDRD report section 4) and the camera-pose tool page."""
