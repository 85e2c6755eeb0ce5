"""socialnav: batched crowd-navigation simulation and social-conformity evaluation.

The package root imports nothing heavy: `import socialnav.metrics` needs NumPy only, and
PyTorch is imported only by learned policies and training. Importing the package registers the
Gymnasium ids (``socialnav/CircleCrossing-v0`` …; Gymnasium 1.x has no plugin loader), which costs
Gymnasium's import (about 0.1 s beyond NumPy's).
"""

# The one place the version is set: pyproject.toml reads it (CHANGELOG.md lists what each release changed).
__version__ = "0.2.0"

from socialnav.sim import registration as _registration  # noqa: E402,F401  (registers the env ids)
