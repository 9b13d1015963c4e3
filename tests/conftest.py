"""Shared set-up of the test suite.

JAX is configured once, before any test builds an array, exactly as the CLI does it: one XLA
device per core (so batches are sharded as in real runs) and float64 available.
"""

from __future__ import annotations

import sanlab

sanlab.configure()
