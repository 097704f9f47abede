(machine: kv=60 kff=0.5 kp_v=350 ti_v=0.012 tc=0.0006 max_accel=2000 period=0.001)
(a triangle with a 30-degree tip: turns of 105, 150 and 105 degrees, F1200)
G90 G17 G94 G21
G0 X0. Y0.
G1 X20. F1200
G1 X10. Y37.3205
G1 X0. Y0.
G1 X10.
