"""Drag coefficient of a sphere against Mach number, as published tables (the `table` drag law of
`physics.air`): C_D is interpolated linearly between the points and held at the end values.
Numbers only (no warp)."""

# Braun's sphere curve as tabulated by DEFRA's QUARRY program, Appendix D (1998),
# http://www.defra.gov.uk/wildlife-countryside/quarry/21.htm (the reference file's 7 points plus
# M = 0, 1.35, 2.2 and 3.0 from the same table).
BRAUN_MACH = (0.00, 0.40, 0.50, 0.60, 1.00, 1.27, 1.35, 1.40, 1.60, 2.20, 3.00)
BRAUN_CD = (0.490, 0.490, 0.500, 0.540, 0.820, 1.000, 1.022, 1.027, 1.015, 0.990, 0.962)

# The G-S ("9/16 inch smooth sphere") standard drag function as tabulated in py-ballisticcalc,
# py_ballisticcalc/drag_tables.py (TableGS), commit 0c92206b; McCoy itself was not read (docs/air.md).
GS_MACH = (0.00, 0.05, 0.10, 0.15, 0.20, 0.25, 0.30, 0.35, 0.40, 0.45, 0.50, 0.55, 0.60, 0.65, 0.70,
           0.75, 0.80, 0.85, 0.90, 0.95, 1.00, 1.05, 1.10, 1.15, 1.20, 1.25, 1.30, 1.35, 1.40, 1.45,
           1.50, 1.55, 1.60, 1.65, 1.70, 1.75, 1.80, 1.85, 1.90, 1.95, 2.00, 2.05, 2.10, 2.15, 2.20,
           2.25, 2.30, 2.35, 2.40, 2.45, 2.50, 2.55, 2.60, 2.65, 2.70, 2.75, 2.80, 2.85, 2.90, 2.95,
           3.00, 3.05, 3.10, 3.15, 3.20, 3.25, 3.30, 3.35, 3.40, 3.45, 3.50, 3.55, 3.60, 3.65, 3.70,
           3.75, 3.80, 3.85, 3.90, 3.95, 4.00)
GS_CD = (0.4662, 0.4689, 0.4717, 0.4745, 0.4772, 0.4800, 0.4827, 0.4852, 0.4882, 0.4920, 0.4970,
         0.5080, 0.5260, 0.5590, 0.5920, 0.6258, 0.6610, 0.6985, 0.7370, 0.7757, 0.8140, 0.8512,
         0.8870, 0.9210, 0.9510, 0.9740, 0.9910, 0.9990, 1.0030, 1.0060, 1.0080, 1.0090, 1.0090,
         1.0090, 1.0090, 1.0080, 1.0070, 1.0060, 1.0040, 1.0025, 1.0010, 0.9990, 0.9970, 0.9956,
         0.9940, 0.9916, 0.9890, 0.9869, 0.9850, 0.9830, 0.9810, 0.9790, 0.9770, 0.9750, 0.9730,
         0.9710, 0.9690, 0.9670, 0.9650, 0.9630, 0.9610, 0.9589, 0.9570, 0.9555, 0.9540, 0.9520,
         0.9500, 0.9485, 0.9470, 0.9450, 0.9430, 0.9414, 0.9400, 0.9385, 0.9370, 0.9355, 0.9340,
         0.9325, 0.9310, 0.9295, 0.9280)


# name -> ((Mach, C_D), ...)
DRAG_TABLES = {"braun": tuple(zip(BRAUN_MACH, BRAUN_CD)), "gs": tuple(zip(GS_MACH, GS_CD))}
