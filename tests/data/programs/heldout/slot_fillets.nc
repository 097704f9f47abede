(machine: kv=50 kff=0.3 kp_v=300 ti_v=0.02 tc=0.0008 max_accel=4000 period=0.001)
(a 34 x 10 slot finish with R2 fillets, F1500)
G90 G17 G94 G21
G0 X0. Y0.
G1 Z-2. F300
G1 X30. F1500
G3 X32. Y2. R2.
G1 Y8.
G3 X30. Y10. R2.
G1 X0.
G3 X-2. Y8. R2.
G1 Y2.
G3 X0. Y0. R2.
G1 X5.
