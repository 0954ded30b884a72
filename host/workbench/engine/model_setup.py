"""What a `Model` fit starts from: fresh terms built from the model's term list, and the design of every
row (features held when small, else computed chunk by chunk; shared through a `DesignCache`)."""

from __future__ import annotations

import copy
from collections.abc import Sequence

import numpy as np
from forcemap.host.workbench.engine import fourier
from forcemap.host.workbench.engine.evidence import Design, DesignCache, TermBlock, design_key
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.table import is_circular
from forcemap.host.workbench.terms.base import Term, TermSpec
from forcemap.host.workbench.terms.registry import build_term, parse_term
from forcemap.host.workbench.terms.simple import ConstTerm


def build_terms(terms: Sequence[str | TermSpec | Term], max_basis: int | None) -> list[Term]:
    """Fresh Term objects for a fit: built from strings and specs, copies of Term objects."""
    built: list[Term] = []
    for t in terms:
        if isinstance(t, str):
            t = parse_term(t, is_circular)
        built.append(build_term(t, is_circular) if isinstance(t, TermSpec) else copy.deepcopy(t))
    if not built:
        raise WorkbenchError("a model needs at least one term")
    if all(t.is_mean for t in built):
        # the weights need at least one feature; a level is the natural one
        built.insert(0, ConstTerm())
    if max_basis is not None:
        for t in built:
            if t.grows_basis and t.dims >= 2:
                t.max_basis = min(t.max_basis, max(max_basis, t.n_basis))
    return built


def build_design(feat: list[tuple[Term, np.ndarray]], memory: DesignCache | None) -> Design:
    """The design of every row: features held when small, else computed chunk by chunk; shared through
    `memory` with any model of the same features on the same inputs."""

    def build(plan: np.ndarray | None) -> Design:
        blocks = [TermBlock(copy.deepcopy(t), Z) for t, Z in feat]
        fast = [i for i, b in enumerate(blocks) if fourier.is_fast(b.term)]
        if not fast:
            return Design(blocks, plan)
        i = max(fast, key=lambda i: blocks[i].shape[1])
        return Design(blocks, plan, (i, blocks[i].term, blocks[i].Z))

    if memory is None:
        return build(None)
    return memory.design(design_key(feat), build)
