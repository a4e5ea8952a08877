"""Layouts of the reduction kernels' arrays, and the ordered sum of their partial rows (SPEC §6).

Owns the facts every kernel shares: the chunk and block sizes, the layout of one row of
partial sums (``I_*``), of the flat result of an evaluation (``O_*``), of the per-asperity
values of a block (``V_*``), of a block's inputs (``X_*``) and slot geometry (``G_*``), of a
commit's sums (``C_*``), the empty arrays passed for "none", :func:`finish` (stress, tangent,
covariance and standard errors, and the contact area fraction with its variance, covariance
with the stress and gradient, from the partial rows, summed in order so that a result does
not depend on the number of threads) and :func:`chunk_stride` (the order chunks go to threads).
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import kernel

CHUNK = 2048
OFFSET = np.int16  # an asperity's place in its chunk (lists of contacts born, of asperities near the path): CHUNK < 2**15
FRESH_ROW = 512  # a trial lists up to this many contacts born per chunk (beyond: the commit searches the chunk)
BIRTH = False
"""The angle policy a template is compiled for (True: birth, False: follow): a placeholder bound per copy by
:mod:`asperity_sim.kernels.specialise`.  numba prunes the branches of a constant before it inlines and types
them, so a copy never compiles the other policy's loops."""
SERIAL_CHUNKS = 8  # a population of up to this many chunks (16384 asperities) runs serially, batches of increments
SERIAL_ACTIVE_CHUNKS = 2  # in a larger one, a trial whose asperities that can touch fit this many chunks runs serially


def fits_serial(n: int, chunks: int = SERIAL_CHUNKS) -> bool:
    """True when n asperities fit ``chunks`` chunks: a population (default) or the asperities of one trial that can
    touch (``SERIAL_ACTIVE_CHUNKS``) small enough for the serial kernel of a path-independent law.  The thresholds
    are measured (docs/performance.md): below them a hand-off to the threads costs more than it saves."""
    return n <= chunks * CHUNK


# layout of one row of partial sums: forces (3), products f_i f_j (11, 22, 33, 12, 13, 23),
# tangent (9), contact and full-slip counts, sum of theta over contacts, partial-slip count,
# contact area a, a², a f_i (3) and d a / d Delta_k (3)
I_F, I_FF, I_T, I_NC, I_NS, I_TH, I_NP, I_A, I_AA, I_AF, I_AT = 0, 3, 9, 18, 19, 20, 21, 22, 23, 24, 27
N_ACC = 30
_FF_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))  # (i, j) of the products f_i f_j, in their order


@kernel(inline="always")
def chunk_stride(n_chunks):
    """A stride g coprime with n_chunks, near n_chunks / golden ratio.

    Chunk ic = (k g) mod n_chunks for k = 0 .. n_chunks-1 visits every chunk once and spreads
    the chunks of each thread's contiguous block of k over the whole height range.  The
    population is sorted by height, so contiguous blocks would give one thread all the
    contacts (low heights) and the other the cheap skipped asperities.  Each chunk still
    writes its own row, so the result does not depend on the threads.
    """
    g = max(1, int(0.6180339887498949 * n_chunks))
    while True:
        a, b = g, n_chunks
        while b:
            a, b = b, a % b
        if a == 1:
            return g
        g -= 1


@kernel()
def finish(partial, n_chunks, n, scale, out):
    """Stress, tangent, covariance, standard error and counts from the partial sums (SPEC §6).

    sigma = N w sum f; the covariance of the mean of n iid draws scaled to stress,
    (N w n)² C_f / n = (N w)² n C_f, multiplied in this order so that 0 stays 0 when (N w)²
    overflows; the standard error is its square root on the diagonal (NaN stays NaN).
    """
    s = np.zeros(N_ACC)
    for ic in range(n_chunks):  # row after row, in order, as numpy's sum over axis 0
        for a in range(N_ACC):
            s[a] += partial[ic, a]
    for i in range(3):
        out[O_STRESS + i] = scale * s[I_F + i]
    for i in range(9):
        out[O_TANGENT + i] = scale * s[I_T + i]
    for m in range(6):
        i, j = _FF_PAIRS[m]
        c = (s[I_FF + m] - s[I_F + i] * s[I_F + j] / n) / (n - 1) * scale * scale * n if n > 1 else 0.0
        out[O_COV + 3 * i + j] = c
        out[O_COV + 3 * j + i] = c
    for i in range(3):
        c = out[O_COV + 4 * i]
        out[O_SE + i] = math.sqrt(c) if c > 0.0 or c != c else 0.0
    n_contact = round(s[I_NC])
    out[O_NC] = n_contact
    out[O_NS] = round(s[I_NS])
    out[O_NP] = round(s[I_NP])
    out[O_TH] = s[I_TH] / n_contact if n_contact else 0.0
    # contact area fraction N w sum a, the variance of its estimate, its covariance with the stress
    # estimate and its gradient d / dDelta, as for the stress
    out[O_AREA] = scale * s[I_A]
    out[O_AREA_VAR] = (s[I_AA] - s[I_A] * s[I_A] / n) / (n - 1) * scale * scale * n if n > 1 else 0.0
    for i in range(3):
        out[O_AREA_COV + i] = ((s[I_AF + i] - s[I_A] * s[I_F + i] / n) / (n - 1) * scale * scale * n
                               if n > 1 else 0.0)
        out[O_AREA_GRAD + i] = scale * s[I_AT + i]



# layout of the flat result of :func:`finish` (one float array per evaluation)
O_STRESS, O_TANGENT, O_COV, O_SE, O_NC, O_NS, O_NP, O_TH, O_NA = 0, 3, 12, 21, 24, 25, 26, 27, 28
O_AREA, O_AREA_VAR, O_AREA_COV, O_AREA_GRAD = 29, 30, 31, 34
N_OUT = 37


# per-asperity values of the vectorised follow loop, one row of BLOCK each: global force (3), tangent
# (9, row-major), contact, full slip, partial slip (0 or 1), theta of a contact, its contact area and
# the area's gradient (3)
V_G, V_T, V_NC, V_NS, V_NP, V_TH, V_A, V_AT = 0, 3, 12, 13, 14, 15, 16, 17
N_VAL = 20
BLOCK = 256  # asperities per block (20 x 256 doubles of values = 40 KiB, in L1)
BLOCKS_PER_CHUNK = CHUNK // BLOCK
# inputs of one block, one row of BLOCK each: Delta_1 - r, cos phi, sin phi, R, u
X_X, X_CP, X_SP, X_R, X_U = 0, 1, 2, 3, 4
N_IN = 5


# per-slot geometry of a block of committed contacts, one row of BLOCK each: inputs (Delta_1 - r, cos phi,
# sin phi, R, u), then delta_n, delta_s, the local increment (normal, s, t), cos/sin theta, theta, d theta/d Delta_1
G_X, G_CP, G_SP, G_R, G_U, G_DN, G_DS, G_RHO, G_DDS, G_DDT, G_CT, G_ST, G_TH, G_TH1 = range(14)
N_GEO = 14


# layout of one row of commit sums: work, stored energy, dissipation, law events, transitions (4 x 4)
C_WORK, C_STORED, C_DISS, C_EVENTS, C_TR = 0, 1, 2, 3, 4
N_COMMIT = 4 + 16

# rows of one committed contact's sums when a commit goes by blocks (``by_slot``): work, stored energy,
# dissipation, law events, transition (4 x code before + code after; -1: no committed contact)
B_WORK, B_STORED, B_DISS, B_EVENTS, B_TR = 0, 1, 2, 3, 4
N_BY_SLOT = 5


EMPTY = np.empty(0)
EMPTY_INDEX = np.zeros(0, dtype=OFFSET)
EMPTY_COUNTS = np.zeros(0, dtype=np.int64)
EMPTY_BY_SLOT = np.zeros((N_BY_SLOT, 0))
