"""The string's block of a linear subsystem in real modal form.

The string's block of the monolithic subsystem (:func:`hammerbit.cosim.reference.monolithic_subsystem`)
is dense: the consistent mass matrix's inverse couples every node.  In its real
modal form, ``z = T w`` with ``T`` the real eigenvectors (2 x 2 blocks for
complex pairs), it is the same linear system with at most two nonzeros a row
in the string's block instead of half of them (tests/test_system_fmu_estimate.py),
so an explicit solver's steps cost far less.  The form is used only where it is well
conditioned: the matrix it is exact for differs from the string's by at most
:data:`MODAL_PERTURBATION_PER_RTOL` times the solver's rtol (relative);
elsewhere the physical form is kept.  Both the monolithic reference and
``DrillingSystem.fmu`` step the string in this form; the form of a matrix is
computed once and remembered (:mod:`hammerbit.memo`).
"""
from __future__ import annotations

import math

import numpy as np

from hammerbit.memo import digest, memo

__all__ = ["MODAL_PERTURBATION_PER_RTOL", "modal_transform", "in_modal_form"]

#: the modal form is used when the matrix it is exact for is within this times the solver's rtol
#: of the string's (largest entry, relative): a perturbation far below what the solver resolves
MODAL_PERTURBATION_PER_RTOL = 1e-3


def modal_transform(A, n: int, rtol: float):
    """``(T, the string's block in modal form)`` for the first ``n`` states of ``A`` (the string),
    ``T`` the real eigenvector matrix (:func:`scipy.linalg.cdf2rdf`, unit columns), or ``None``
    when the form is not well conditioned (see :data:`MODAL_PERTURBATION_PER_RTOL`)."""
    block = np.ascontiguousarray(np.asarray(A, dtype=float)[:n, :n])
    T, lam_r, perturbation = memo(digest("modal form", block), lambda: _real_modal_form(block))
    if not perturbation <= MODAL_PERTURBATION_PER_RTOL * rtol:      # NaN where T is singular
        return None
    return T, lam_r


def _real_modal_form(block):
    """``(T, lam_r, perturbation)``: the real eigenvector matrix of ``block`` and its real block
    diagonal form, and the largest entry of ``T lam_r T^-1 - block`` relative to ``block``'s
    (NaN where that matrix is not finite)."""
    import scipy.linalg as sl
    lam, vec = np.linalg.eig(block)
    lam_r, T = sl.cdf2rdf(lam, vec / np.linalg.norm(vec, axis=0))
    with np.errstate(all="ignore"):
        exact_for = np.linalg.solve(T.T, (T @ lam_r).T).T          # T lam_r T^-1
    if not np.all(np.isfinite(exact_for)):
        return T, lam_r, math.nan
    return T, lam_r, float(np.max(np.abs(exact_for - block)) / max(np.max(np.abs(block)), np.finfo(float).tiny))


def in_modal_form(ext, n: int, rtol: float):
    """``(subsystem, Tz)``: the :class:`~hammerbit.model.stepping.LinearSubsystem` ``ext`` with its
    string block (the first ``n`` states) in real modal form, ``z = Tz w``; ``(ext, None)`` where
    that form is not well conditioned.  The hammer's link force ``G . z`` is the same in both.

    On one BLAS thread: the eigenproblem (hundreds of states) runs many times slower on threads
    that share two busy cores, and its result does not depend on the machine's thread count."""
    from hammerbit.model.string_step import one_blas_thread
    with one_blas_thread():
        return _modal_subsystem(ext, n, rtol)


def _modal_subsystem(ext, n: int, rtol: float):
    from hammerbit.model.stepping import LinearSubsystem
    A = np.asarray(ext.A, dtype=float)
    modal = modal_transform(A, n, rtol)
    if modal is None:
        return ext, None
    T, lam_r = modal
    nz = A.shape[0]
    Tz = np.eye(nz)
    Tz[:n, :n] = T
    Am = A.copy()
    Am[:n, :n] = lam_r
    Am[:n, n:] = np.linalg.solve(T, A[:n, n:])
    Am[n:, :n] = A[n:, :n] @ T
    # entries that are rounding of an exact zero (the eigenvectors' tiny components) are dropped
    Am[np.abs(Am) < np.finfo(float).eps * np.max(np.abs(Am))] = 0.0
    return LinearSubsystem(A=Am, H=np.linalg.solve(Tz, ext.H), G=np.asarray(ext.G) @ Tz,
                           g=np.asarray(ext.g, dtype=float), z0=np.linalg.solve(Tz, ext.z0)), Tz
