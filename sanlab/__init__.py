"""sanlab: discover how planar creatures can move with sensor-actuator networks.

After van de Panne & Fiume, "Sensor-Actuator Networks", SIGGRAPH 1993.
"""

__version__ = "0.2.0"

