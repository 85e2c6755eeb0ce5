"""socialnav: batched crowd-navigation simulation and social-conformity evaluation.

The package root imports nothing heavy: `import socialnav.metrics` needs NumPy only, and
PyTorch is imported only by learned policies and training. Importing the package registers the
Gymnasium ids (``socialnav/CircleCrossing-v0`` …; Gymnasium 1.x has no plugin loader), which costs
Gymnasium's import (about 0.1 s beyond NumPy's).
"""

# The one place the version is set: pyproject.toml reads it (CHANGELOG.md lists what each release changed).
__version__ = "0.2.0"

from socialnav.envs import registration as _registration  # noqa: E402,F401  (registers the env ids)
from socialnav.envs.render import register_viewer as _register_viewer  # noqa: E402


def _env_viewer(size_px: tuple[int, int]):
    # The package root wires the viz layer into the envs: envs never import viz.
    from socialnav.viz.env_render import EnvViewer

    return EnvViewer(size_px)


_register_viewer(_env_viewer)
