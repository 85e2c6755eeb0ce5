"""The shipped presets (``<name>.yaml``; ``socialnav preset list``) and training configurations."""
