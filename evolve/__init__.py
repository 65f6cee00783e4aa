"""The cyclic genetic algorithm on a fast table simulation of the ServoBot colony.

Pure numerics: nothing here imports MuJoCo. See ``../shared/SPEC.md`` for the contract.
``evolve.evaluate`` and ``evolve.evaluate_colony`` (the numba kernels' entry points) are
imported on first use, so that importing settings, tables or the codec does not load numba.
"""

from typing import Any

__all__ = ["ColonyEvaluation", "Evaluation", "evaluate", "evaluate_colony"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        from evolve import evaluation

        return getattr(evaluation, name)
    raise AttributeError(f"module 'evolve' has no attribute {name!r}")
