"""The cyclic genetic algorithm on a fast table simulation of the ServoBot colony.

Pure numerics: nothing here imports MuJoCo. See ``../shared/SPEC.md`` for the contract.
"""

from evolve.evaluate import Evaluation, evaluate

__all__ = ["Evaluation", "evaluate"]
