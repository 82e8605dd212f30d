"""rbref: an independent reference generator of FRF recordings of a softly suspended rigid
body, for testing rbprops on data its own simulator did not make.

Formulation (see README.md): the body's pose under finite rotations, the static
equilibrium of the potential energy (springs, elastic cords, gravity), the tangent
stiffness as the finite-difference Hessian at equilibrium, and FRFs from a state-space
eigen-decomposition in pole–residue form.

    import rbref
    case = rbref.load("case.toml")
    result = rbref.generate(case)          # result.frequency_hz, result.frf[e, c, l], result.truth
    rbref.write_uff(result, "out.uff")
"""
from .case import Case, CaseError, load
from .generate import Result, Terms, generate
from .writers import write_json, write_npz, write_time_uff, write_truth, write_uff

__all__ = ["Case", "CaseError", "load", "Result", "Terms", "generate",
           "write_json", "write_npz", "write_time_uff", "write_truth", "write_uff"]
