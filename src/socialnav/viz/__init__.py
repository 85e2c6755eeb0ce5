"""Seeing what the robot did: episode plots and animations, metric figures, the HTML report.

Needs the ``viz`` extra (matplotlib, Pillow); everything draws on matplotlib's Agg canvas, so no
window or display is needed. See docs/visualisation.md.
"""
