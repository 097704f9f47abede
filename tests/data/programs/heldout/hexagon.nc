(machine: kv=35 kff=0.7 kp_v=500 ti_v=0.008 tc=0.0004 max_accel=6000 period=0.001)
(a regular hexagon of 10 mm sides: six 60-degree turns, F2500)
G90 G17 G94 G21
G0 X0. Y0.
G1 X10. F2500
G1 X15. Y8.6603
G1 X10. Y17.3205
G1 X0. Y17.3205
G1 X-5. Y8.6603
G1 X0. Y0.
G1 X10.
