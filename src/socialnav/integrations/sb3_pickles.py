"""What the pickled fields of a Stable-Baselines3 model zip name, read without unpickling them.

SB3 writes each ``:serialized:`` field of a model's ``data`` JSON as base64 of a (cloud)pickle. socialnav
never unpickles one (it rebuilds every field, ``sb3_files.safe_custom_objects``); it reads a field as a
list of pickle opcodes (``pickletools.genops``, which runs nothing) and refuses a file whose fields name
an object no SB3 model holds (``os.system``, ``io.open``, ``subprocess.Popen``...): a crafted file.
"""

from __future__ import annotations

import base64
import binascii
import pickletools
from typing import Any

#: What the pickled fields of a Stable-Baselines3 model name (its classes, schedules, buffers, spaces,
#: torch optimizers and activations, NumPy arrays and generators, a function pickled by cloudpickle):
#: module prefixes, and exact (module, name) pairs for the modules that also hold dangerous functions.
_SB3_MODULES = ("stable_baselines3.", "sb3_contrib.", "gymnasium.spaces.", "torch.optim.",
                "torch.nn.modules.", "cloudpickle.", "numpy.random.")
_SB3_OBJECTS = frozenset({
    ("collections", "deque"), ("collections", "OrderedDict"), ("copyreg", "_reconstructor"),
    ("numpy", "dtype"), ("numpy", "ndarray"), ("numpy._core.multiarray", "scalar"),
    ("numpy._core.multiarray", "_reconstruct"), ("numpy._core.numeric", "_frombuffer"),
    ("numpy.core.multiarray", "scalar"), ("numpy.core.multiarray", "_reconstruct"),
    ("numpy.core.numeric", "_frombuffer"), ("torch", "float32"), ("torch", "float64"),
    *(("builtins", name) for name in ("object", "bool", "int", "float", "complex", "str", "bytes", "tuple",
                                      "list", "dict", "set", "frozenset", "slice", "range")),
})
_STRING_OPS = frozenset({"SHORT_BINUNICODE", "BINUNICODE", "BINUNICODE8", "UNICODE", "SHORT_BINSTRING",
                         "BINSTRING", "STRING"})


def foreign_object(encoded: Any) -> str | None:
    """The first object a pickled field names that no SB3 model holds (``"module.name"``), else None.

    Args:
        encoded: the field's ``:serialized:`` value (base64 of a pickle).

    Raises:
        ValueError: ``"not base64"`` or ``"not a pickle (...)"``, completing "field K of the model file is".
    """
    try:
        raw = base64.b64decode(encoded, validate=True)
    except (binascii.Error, TypeError, ValueError):
        raise ValueError("not base64") from None
    strings: list[str | None] = []  # the strings pushed so far, where STACK_GLOBAL finds its names
    memo: dict[int, str | None] = {}
    try:
        for op, arg, _ in pickletools.genops(raw):
            if op.name in _STRING_OPS:
                strings.append(arg if isinstance(arg, str) else str(arg))
            elif op.name == "MEMOIZE":
                memo[len(memo)] = strings[-1] if strings else None
            elif op.name in ("PUT", "BINPUT", "LONG_BINPUT"):
                memo[int(arg)] = strings[-1] if strings else None
            elif op.name in ("GET", "BINGET", "LONG_BINGET"):
                strings.append(memo.get(int(arg)))
            elif op.name in ("GLOBAL", "INST", "STACK_GLOBAL"):
                if op.name != "STACK_GLOBAL":
                    module, name = arg.split(" ", 1)
                else:
                    module, name = (strings[-2], strings[-1]) if len(strings) >= 2 else (None, None)
                if not (isinstance(module, str) and isinstance(name, str)
                        and (module.startswith(_SB3_MODULES) or (module, name) in _SB3_OBJECTS)):
                    return f"{module}.{name}"
    except (ValueError, IndexError, TypeError) as err:
        raise ValueError(f"not a pickle ({err})") from None
    return None
