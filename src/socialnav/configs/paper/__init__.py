"""The paper's published numbers (Wang et al. 2022, Tables I–III) transcribed for ``socialnav reproduce``."""
