"""Other engines' formats: ``mjcf`` writes a creature as a MuJoCo model (export only; NumPy, no
JAX), for cross-checking the simulator (``tests/sim/test_mujoco.py``) and benchmarking it
(``benchmarks/``)."""
