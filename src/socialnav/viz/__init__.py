"""Seeing what the robot did: episode plots and animations, metric figures, the HTML report.

Needs the ``viz`` extra (matplotlib, Pillow); everything draws on matplotlib's Agg canvas, so no
window or display is needed. See docs/visualisation.md.
"""


def require_viz() -> None:
    """Raises a one-line error naming the extra to install when matplotlib or Pillow is missing."""
    try:
        import matplotlib  # noqa: F401
        import PIL  # noqa: F401
    except ImportError as err:
        raise RuntimeError(
            f"drawing needs matplotlib and Pillow ({err.name} is missing): pip install 'socialnav[viz]'"
        ) from None
