"""sanlab: discover how planar creatures can move with sensor-actuator networks.

After van de Panne & Fiume, "Sensor-Actuator Networks", SIGGRAPH 1993.
"""

__version__ = "0.1.0"


def configure() -> None:
    """Does nothing; kept so that scripts and notebooks that call it keep working.

    Until issue 46 this set up JAX for the XLA engine (one XLA device per core, float64, the
    persistent compilation cache). The simulator is now one compiled kernel that needs no set-up
    (``sanlab.sim``), and sanlab no longer uses JAX.
    """
