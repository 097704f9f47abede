(machine: kv=30 kff=0.5 kp_v=300 ti_v=0.015 tc=0.0008 max_accel=3000 period=0.001)
(a profile in the ZX plane: steps down and across with sharp corners and one R3 arc, G18, F1000)
G90 G18 G94 G21
G0 X0. Y0.
G1 X10. F1000
G1 Z-3.
G1 X20.
G2 X26. Z-3. I3. K0.
G1 X30.
G1 Z0.
G1 X40.
