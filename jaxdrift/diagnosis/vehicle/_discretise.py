"""Exact discretisation of a linear system driven by piecewise-cubic inputs, the diagonal
recursion that runs it, and the small polynomial helpers of the residual pipeline."""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.signal


def _discretise(A: np.ndarray, B: np.ndarray, h: float):
    """Phi = exp(A h) and G[p] = int_0^h exp(A (h - s)) B s^p ds, p = 0..3 (shape (4, nx, nu)).

    One matrix exponential of the system augmented with the input and its three derivatives
    (the 4th derivative vanishes on a cubic piece): for ``z = [x, u, u', u'', u''']``,
    ``x(h) = E01 u(0) + E02 u'(0) + E03 u''(0) + E04 u'''(0)`` and ``u^(p)(0) = p! c_p``.
    """
    nx, nu = B.shape
    N = nx + 4 * nu
    M = np.zeros((N, N))
    M[:nx, :nx] = A
    M[:nx, nx:nx + nu] = B
    for i in range(3):
        r0 = nx + i * nu
        M[r0:r0 + nu, r0 + nu:r0 + 2 * nu] = np.eye(nu)
    E = scipy.linalg.expm(M * h)
    Phi = E[:nx, :nx]
    G = np.empty((4, nx, nu))
    fact = (1.0, 1.0, 2.0, 6.0)
    for p in range(4):
        G[p] = E[:nx, nx + p * nu:nx + (p + 1) * nu] * fact[p]
    return Phi, G


def _mm(X: np.ndarray, M: np.ndarray) -> np.ndarray:
    """X @ M for a tall X and a tiny M, through real BLAS calls only (complex ones are slow
    here when threads contend)."""
    if np.iscomplexobj(X) or np.iscomplexobj(M):
        Xr, Xi = np.real(X), np.imag(X)
        Mr, Mi = np.real(M), np.imag(M)
        return (Xr @ Mr - Xi @ Mi) + 1j * (Xr @ Mi + Xi @ Mr)
    return X @ M


def _run_recursion(Phi: np.ndarray, v: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """x_{k+1} = Phi x_k + v_k, x_0 given; v of shape (n-1, nx). Returns (n, nx).

    Diagonalises Phi and runs each mode through ``lfilter`` (a C loop): the chassis-spring modes
    are distinct (over)damped ones, so the eigenvectors are well conditioned; a plain loop is
    the fallback otherwise.
    """
    n = v.shape[0] + 1
    lam, V = np.linalg.eig(Phi)
    if np.linalg.cond(V) < 1e8:
        Vi = np.linalg.inv(V)
        w = _mm(v, Vi.T)  # (n-1, nx)
        w0 = Vi @ x0
        out = np.empty((n, len(lam)), dtype=complex)
        for i, l in enumerate(lam):
            u = np.concatenate([[w0[i]], w[:, i]])
            out[:, i] = scipy.signal.lfilter([1.0], [1.0, -l], u)
        x = _mm(out, V.T).real
        return x
    x = np.empty((n, len(x0)))
    x[0] = x0
    for k in range(n - 1):
        x[k + 1] = Phi @ x[k] + v[k]
    return x


def _poly_coeffs(sp) -> np.ndarray:
    """Ascending local coefficients (4, n-1) of a scipy cubic piecewise polynomial."""
    c = sp.c
    return c[::-1]


def _deriv_coeffs(c: np.ndarray) -> np.ndarray:
    """Ascending coefficients of the derivative of a cubic (the cubic term becomes zero)."""
    out = np.zeros_like(c)
    out[0], out[1], out[2] = c[1], 2 * c[2], 3 * c[3]
    return out


def _numerov(m: np.ndarray) -> np.ndarray:
    """(m_{k-1} + 10 m_k + m_{k+1}) / 12 for k = 1..n-2."""
    return (m[:-2] + 10.0 * m[1:-1] + m[2:]) / 12.0


def _d2(y: np.ndarray, h: float) -> np.ndarray:
    return (y[2:] - 2.0 * y[1:-1] + y[:-2]) / (h * h)

