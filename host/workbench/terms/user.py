"""User terms: a Python function `f(z, **params)` of the user's, loaded explicitly and checked on every call.

`module:function` is the file `module.py` in the current folder, or an installed module; nothing is added
to sys.path. A function that raises, or returns NaN, inf or the wrong shape, is named in a one-line error.
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import math
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import numpy as np
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.terms.base import Term


class UserTerm(Term):
    """A user's Python function `f(z, **params)` loaded by `module:function`; its parameters fitted as a mean function."""

    kind = "user"
    is_mean = True

    def __init__(self, name: str, ref: str) -> None:
        self.inputs, self.ref = (name,), ref
        self.func = load_function(ref)
        try:
            sig = inspect.signature(self.func)
        except (TypeError, ValueError):
            raise WorkbenchError(
                f"user term '{ref}': cannot read the function's parameters"
            ) from None
        names = list(sig.parameters)
        if not names:
            raise WorkbenchError(
                f"{ref}: the function must take the covariate as its first argument"
            )
        self.names = names[1:]
        self.init = []
        for p in self.names:
            default = sig.parameters[p].default
            if default is inspect.Parameter.empty:
                self.init.append(1.0)
            elif isinstance(default, int | float) and math.isfinite(default):
                self.init.append(float(default))
            else:
                raise WorkbenchError(
                    f"user term '{ref}': parameter '{p}' must default to a finite number (its "
                    f"starting value), not {default!r}"
                )

    def describe(self) -> str:
        return f"user({self.inputs[0]}, {self.ref})"

    def theta_init(self):
        return np.array(self.init, float)

    def theta_bounds(self):
        return [(-1e6, 1e6)] * len(self.names)

    def mean(self, Z, theta):
        params = dict(zip(self.names, (float(t) for t in theta), strict=True))
        try:
            out = np.asarray(self.func(Z[:, 0].copy(), **params), float)
        except Exception as exc:  # the user's code: any failure is explained in one line
            raise WorkbenchError(
                f"user term '{self.ref}': the function raised {type(exc).__name__}: {exc}"
            ) from None
        if out.shape not in ((), (len(Z),)):
            raise WorkbenchError(
                f"user term '{self.ref}': the function returned shape {out.shape}; it must return "
                f"one value per sample ({len(Z)},) or a single number"
            )
        if not np.all(np.isfinite(out)):
            bad = int(np.size(out) - np.count_nonzero(np.isfinite(out)))
            raise WorkbenchError(
                f"user term '{self.ref}': the function returned NaN or inf for {bad} of "
                f"{np.size(out)} value(s) with {params}; it must give finite numbers"
            )
        return np.broadcast_to(out, (len(Z),)).copy()

    def params(self, h, w):
        return {k: float(v) for k, v in zip(self.names, h, strict=True)}


# user modules loaded from a file, by absolute path: loaded once, never put in sys.modules
_USER_MODULES: dict[Path, ModuleType] = {}


def _module_from_file(path: Path, ref: str) -> ModuleType:
    path = path.resolve()
    if path not in _USER_MODULES:
        spec = importlib.util.spec_from_file_location(f"forcemap_user_{path.stem}", path)
        if spec is None or spec.loader is None:
            raise WorkbenchError(f"user term '{ref}': cannot load {path} as Python")
        module = importlib.util.module_from_spec(spec)
        try:
            spec.loader.exec_module(module)
        except Exception as exc:  # the user's code
            raise WorkbenchError(
                f"user term '{ref}': {path} failed to load ({type(exc).__name__}: {exc})"
            ) from None
        _USER_MODULES[path] = module
    return _USER_MODULES[path]


def load_function(ref: str) -> Callable:
    """`module:function`: the file `module.py` in the current folder, or an installed module of that
    name; `path/to/file.py:function` names the file. Nothing is added to sys.path."""
    if ":" not in ref:
        raise WorkbenchError(f"user term '{ref}': write it as module:function")
    mod_name, func_name = ref.rsplit(":", 1)
    as_file = Path(mod_name if mod_name.endswith(".py") else mod_name.replace(".", "/") + ".py")
    if as_file.is_file():
        module = _module_from_file(as_file, ref)
    elif mod_name.endswith(".py"):
        raise WorkbenchError(f"user term '{ref}': no such file {as_file}")
    else:
        try:
            module = importlib.import_module(mod_name)
        except ImportError as exc:
            raise WorkbenchError(
                f"user term '{ref}': cannot import '{mod_name}': no file {as_file} here and no "
                f"installed module of that name ({exc})"
            ) from None
        except Exception as exc:  # the user's code
            raise WorkbenchError(
                f"user term '{ref}': module '{mod_name}' failed to load ({type(exc).__name__}: {exc})"
            ) from None
    func = getattr(module, func_name, None)
    if not callable(func):
        raise WorkbenchError(
            f"user term '{ref}': module '{mod_name}' has no function '{func_name}'"
        )
    return func
