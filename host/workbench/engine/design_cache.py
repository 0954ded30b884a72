"""Designs shared by content: models with the same features on the same inputs (a vector's components, its
along- and across-flow components) compute one Gram matrix, and the cross-validation folds share its pass."""

from __future__ import annotations

import hashlib
import pickle

import numpy as np


class DesignCache:
    """Designs by content, so that models with the same features on the same inputs (the east and north
    components of a vector, its along- and across-flow components) compute one Gram matrix, and the
    cross-validation folds `plan` share its pass. Keys are hashes of the terms' set-up state and inputs
    (`design_key`); the `size` latest designs are kept. A model's `memory`: copies of a model share it."""

    def __init__(self, size: int = 4) -> None:
        self.size = size
        self.plan: np.ndarray | None = None
        self._designs: dict[str, object] = {}

    def __deepcopy__(self, memo) -> DesignCache:
        return self

    def __getstate__(self) -> dict:
        # a pickled cache (a pickled model's `memory`) starts empty: its contents are derived data
        return {"size": self.size}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["size"])

    def design(self, key: str, build) -> object:
        if key in self._designs:
            self._designs[key] = self._designs.pop(key)
        else:
            self._designs[key] = build(self.plan)
            while len(self._designs) > self.size:
                self._designs.pop(next(iter(self._designs)))
        return self._designs[key]


def design_key(blocks: list[tuple[object, np.ndarray]]) -> str:
    """A hash of feature terms (their class and set-up state: the basis) and their inputs."""
    h = hashlib.sha1()
    for term, Z in blocks:
        state = {k: v for k, v in sorted(vars(term).items()) if k != "max_basis"}
        h.update(pickle.dumps((type(term).__name__, state)))
        h.update(repr(Z.shape).encode())
        h.update(np.ascontiguousarray(Z).tobytes())
    return h.hexdigest()
