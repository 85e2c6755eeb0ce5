"""socialnav: batched crowd-navigation simulation and social-conformity evaluation.

The package root imports nothing heavy: `import socialnav.metrics` needs NumPy only, and
PyTorch is imported only by learned policies and training.
"""

__version__ = "0.1.0"
