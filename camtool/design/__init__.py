"""Arm design optimisation: the two-step MOPSO with potential-field repulsion of
Sun et al. 2023 (section 2.2), with NSGA-II (pymoo, optional) for comparison.

- ``pareto``: dominance, the bounded archive, hypercube roulette.
- ``mopso``: the generic two-step MOPSO (``run_mopso``), repulsion, narrowing.
- ``objectives``: the arm problem of a job (length, singularities, unreachable).
- ``nsga2``: the pymoo NSGA-II wrapper and the hypervolume indicator.
- ``study``: run, choose, verify at full resolution, write the chosen job.
- ``plots``: Figures 5-6 style plots and the front.
"""
from .mopso import MopsoResult, MopsoSettings, narrow_ranges, repulsion_velocity, run_mopso
from .objectives import DesignProblem, Evaluation, Variable, parse_vary
from .pareto import ParetoArchive, dominates, nondominated_mask
from .study import DesignStudy, choose_design, design_arm

__all__ = ["DesignProblem", "DesignStudy", "Evaluation", "MopsoResult", "MopsoSettings", "ParetoArchive",
           "Variable", "choose_design", "design_arm", "dominates", "narrow_ranges", "nondominated_mask",
           "parse_vary", "repulsion_velocity", "run_mopso"]
