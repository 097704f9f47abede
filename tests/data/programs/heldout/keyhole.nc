(machine: kv=45 kff=0.2 kp_v=400 ti_v=0.01 tc=0.0005 max_accel=5000 period=0.001)
(a keyhole: a slot, a half circle of R5 in two quarter arcs, and back down, sharp joins, F1800)
G90 G17 G94 G21
G0 X0. Y0.
G1 X20. F1800
G1 X20. Y10.
G2 X25. Y15. I5. J0.
G2 X30. Y10. I0. J-5.
G1 Y0.
G1 X40.
