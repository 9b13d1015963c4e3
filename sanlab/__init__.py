"""sanlab: discover how planar creatures can move with sensor-actuator networks.

After van de Panne & Fiume, "Sensor-Actuator Networks", SIGGRAPH 1993.
"""

__version__ = "0.1.0"


def configure() -> None:
    """Set up JAX for sanlab in this process; the one place that changes global JAX settings.

    Idempotent. It must run before JAX creates its CPU backend (the first array or ``jax.devices()``
    call) for the device split to apply. It:

    - splits the host into one XLA device per available core (``XLA_FLAGS``
      ``--xla_force_host_platform_device_count``, unless the variable already sets it), so that a
      batch is sharded over every core instead of running on one;
    - turns on ``jax_enable_x64``, so that ``dtype="float64"`` models really are float64 (float32
      models stay float32: every array sanlab builds is given its dtype);
    - points JAX's persistent compilation cache at :func:`sanlab._jax.cache_dir` (``SANLAB_CACHE``
      moves it, ``SANLAB_NO_COMPILE_CACHE=1`` turns it off);
    - imports JAX with SIGINT and SIGTERM held back, and delivers one that came once the import
      is done (a KeyboardInterrupt raised inside jaxlib's native initialisation aborts Python).

    Importing sanlab or any of its modules changes none of this. The CLI calls it at the start of
    every command that simulates; ``sim.compile_creature`` calls it too, so a library user's first
    compiled creature configures the process if nothing did before.
    """
    from sanlab import _jax

    _jax.configure()
