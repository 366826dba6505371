"""Bounds for "agrees to round-off", worked out from the arithmetic (issue 43).

Why this module exists
----------------------
A bound read off one machine's result (``assert err < 2e-15`` because 1.3e-15 was seen)
fails on another machine. numpy's OpenBLAS picks its kernels by CPU at start-up
(``OPENBLAS_CORETYPE``: Prescott, Sandybridge, Haswell, Zen, SkylakeX, ...) and by thread
count; the kernels sum in other orders, fuse multiply-adds or not, and block differently,
so the last bits of every BLAS/LAPACK result differ between machines. numba's compiled
loops and numpy's vectorised paths do the same. A test that claims two computations agree
"to round-off" must therefore hold for any order of the rounding errors, not for the one
order of the machine that wrote it.

The model (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., 2.2, 3.1)
---------------------------------------------------------------------------------------
- Every IEEE operation (``+ - * /``, ``sqrt``, a fused multiply-add) is correctly
  rounded: relative error at most ``u = EPS / 2``. libm's ``sin``, ``cos``, ``atan2``,
  ``exp``, ``log`` are within 1 ulp (relative error at most ``EPS``): count each as two
  operations.
- A chain of ``n`` operations whose rounding errors are passed on with a gain of at most 1
  (a sum, a dot product, a product of rotations, a Horner recurrence) has an absolute error
  of at most ``gamma_n |x| ~ n u |x|``, where ``|x|`` is the size of the *operands*, not of
  the result: ``R^T R - I`` is a sum of O(1) terms whose result is 1e-16, so its scale is 1.
- Two evaluations of one quantity in different orders (another BLAS kernel, a compiled
  loop against numpy, a block against single steps) each carry such an error, so they
  differ by at most ``2 gamma_n ~ n EPS``. Comparing with an exact closed form, only one
  side rounds: the same bound holds with a factor 2 to spare.
- An error ``d`` in the inputs of a map with (absolute) condition number ``cond`` moves its
  output by at most ``cond * d``: a linear solve by ``kappa(A)``, a polar factor by
  ``2 / (s_2 + s_3)``, a recurrence over ``N`` steps by its growth over the steps.

So the bound is :func:`roundoff`: ``K * n_ops * EPS * scale * cond``, with ``K = 2``, the
one safety multiple of the whole suite. The model already gives the worst case (every
rounding error of the chain aligned, which needs ``n`` errors of one sign); ``K`` covers
the counts themselves, which are the long dependency chain of an algorithm counted by
hand (a library routine, pairwise against sequential sums), not traced instruction by
instruction. Each use states its ``n_ops``, ``scale`` and ``cond`` in a comment.

What it promises: a test that uses it fails only when the two sides differ by more than
rounding in *some* order can explain, i.e. a real difference in the arithmetic (a term
left out, a wrong sign, a state not carried over), on every machine and BLAS kernel. What
it does not promise: that the bound is tight. A worst-case bound is typically 10 to 100
times the error seen (random rounding errors grow like ``sqrt(n)``, not ``n``), which is
still far below any arithmetic mistake the tests look for (those are 1e-8 and up).
"""
import numpy as np

#: machine epsilon of float64, 2**-52 = 2.22e-16 (the unit round-off ``u`` is half of it)
EPS = float(np.finfo(float).eps)

#: the one safety multiple on the counted operation chains (see the module docstring)
K = 2.0


def roundoff(n_ops, scale=1.0, cond=1.0):
    """Largest difference that rounding can make: ``K * n_ops * EPS * scale * cond``.

    ``n_ops``: the longest chain of rounded operations between the inputs and the compared
    value (libm functions count 2; a recurrence over ``N`` steps counts ``N`` times its
    step). ``scale``: the size of the operands of that chain (a scalar, or an array that
    broadcasts against the compared values for an elementwise, relative, bound).
    ``cond``: how much the compared value amplifies a relative error of its inputs (1 for
    sums, products and rotations). Returns a float or an array like ``scale``.
    """
    if n_ops <= 0:
        raise ValueError(f'n_ops must be positive, got {n_ops}')
    return K * n_ops * EPS * np.asarray(scale, dtype=float) * cond


def assert_roundoff(actual, desired, n_ops, scale=None, cond=1.0, what=''):
    """Assert ``|actual - desired| <= roundoff(n_ops, scale, cond)`` elementwise.

    ``scale`` defaults to the largest ``|desired|`` (the operands of most comparisons are
    of the size of the result; pass it where they are not). NaN must meet NaN. The message
    gives the largest difference in units of ``EPS * scale`` and the bound's share of it.
    """
    a = np.asarray(actual, dtype=float)
    d = np.asarray(desired, dtype=float)
    a, d = np.broadcast_arrays(a, d)
    nan_a, nan_d = np.isnan(a), np.isnan(d)
    assert np.array_equal(nan_a, nan_d), f'{what}: NaN in one side only'
    if scale is None:
        finite = d[~nan_d]
        scale = float(np.abs(finite).max()) if finite.size else 1.0
        scale = scale or 1.0
    bound = np.broadcast_to(roundoff(n_ops, scale, cond), a.shape)
    diff = np.where(nan_a, 0.0, np.abs(a - d))
    ratio = np.max(diff / bound) if diff.size else 0.0
    assert ratio <= 1.0, (
        f'{what}: largest difference {diff.max():.3g} is {ratio:.3g} x the round-off bound '
        f'(K={K:g} x n_ops={n_ops} x EPS x scale x cond={cond:.3g}); '
        'more than any order of rounding can explain')
