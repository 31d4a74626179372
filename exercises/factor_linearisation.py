"""Chapter 7 exercise: the generic linearisation, H and b of a factor graph in one block-sparse pattern.

The graph has N variables of mixed tangent sizes ``dims`` (N,); variable ``v``'s step is the slice
``offsets[v] : offsets[v] + dims[v]`` of the whole step (``offsets`` the running sum of ``dims``).
Its factors come in groups of one type: group ``g`` has ``M_g`` factors on ``s_g`` variables each,
``keys[g]`` (M_g, s_g), and at every linearisation a whitened residual ``r`` (M_g, m_g) and one
Jacobian block per slot, ``J_a`` (M_g, m_g, dims[keys[g][:, a]]) (all variables of a slot have one kind,
so one size). Then, summed over all factors,

    H = sum J^T J      b = sum J^T r      chi2 = sum r^T r

where a factor's J (m, n) is zero but for its blocks in its variables' columns. Derive which blocks
of H one factor adds to; the pattern (which entries of H can be nonzero) depends on ``keys`` only,
so find it once, in ``__init__``, and make ``assemble`` a scatter of numbers into it (chapters 2 and
6 did this for one kind of variable; here the sizes differ).
Fixed variables are held still as in chapters 2 and 6: their rows and columns of H are zero but for
the identity on their diagonal block, their entries of b zero.
``python -m autograder hint BlockSparseAssembler 1`` if you are stuck.

Inputs at the edges of the contract (each is a check input):
- one factor (M = 1) of one variable (N = 1)
- a factor of one variable (a prior)
- a factor from a later variable to an earlier one
- two factors on the same variables (their blocks add up)
- no variable fixed
- a fixed variable that is not the first

Allowed imports: numpy, scipy.
"""

import numpy as np
import scipy.sparse as sp


class BlockSparseAssembler:
    """``assemble`` H (upper triangle, CSC), b and chi2 of whitened factor blocks, into a pattern found once.

    Args of ``__init__``: ``dims`` (N,) int tangent sizes; ``keys``: one (M_g, s_g) int array per group;
    ``fixed``: (K,) int indices of fixed variables.
    ``diagonal_positions`` (n,): where ``H``'s diagonal entries sit in the returned matrix's ``data``.
    """

    def __init__(self, dims, keys, fixed):
        raise NotImplementedError("TODO factor_linearisation.BlockSparseAssembler.__init__: not implemented yet")

    def assemble(self, blocks):
        """``(H, b, chi2)`` from ``blocks``: per group ``(r (M_g, m_g), [J_a (M_g, m_g, d_a)])``, whitened.

        H is the upper triangle (n, n) as a scipy CSC matrix, b (n,), chi2 a float.
        """
        raise NotImplementedError("TODO factor_linearisation.BlockSparseAssembler.assemble: not implemented yet")
