"""Other engines' and machines' formats: ``mjcf`` writes a creature as a MuJoCo model (export
only; NumPy, no JAX), for cross-checking the simulator (``tests/sim/test_mujoco.py``) and
benchmarking it (``benchmarks/``); ``san_c`` writes a gait's SAN as a C99 header (``sanlab export
GAIT --c``), for a microcontroller."""
