"""Other engines' and machines' formats: ``mjcf`` writes a creature as a MuJoCo model (NumPy only),
for MuJoCo's viewer (``sanlab export-mjcf``), for cross-checking the simulator
(``tests/sim/test_mujoco.py``) and benchmarking it (``benchmarks/``); ``mjcf_import`` reads a
planar MJCF model into a creature file, compiled by MuJoCo itself (``sanlab import-mjcf``);
``san_c`` writes a gait's SAN as a C99 header (``sanlab export GAIT --c``), for a
microcontroller."""
