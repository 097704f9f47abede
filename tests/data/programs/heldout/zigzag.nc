(machine: kv=40 kff=0.6 kp_v=400 ti_v=0.01 tc=0.0005 max_accel=5000 period=0.0005)
(a zigzag of 10 mm passes 1 mm apart: 180-degree turns through 1 mm steps, F2000, 0.5 ms controller)
G90 G17 G94 G21
G0 X0. Y0.
G1 X10. F2000
G1 Y1.
G1 X0.
G1 Y2.
G1 X10.
G1 Y3.
G1 X0.
G1 Y4.
G1 X10.
