"""Fixed-point text of a table of floats and one text column, compiled (the result CSV).

Python's ``%`` formatting of the 1.6 million numbers of a 1200 s, 100 Hz replay's CSV
took 0.3-0.4 s, more than the whole fine alignment of some filters; :func:`format_table`
writes the same text from a numba kernel (``cache=True``) in a few milliseconds.

The text follows Python's ``'%.{d}f' % x``: an optional ``-`` (also for ``-0.0`` and
for negatives that round to zero), the integer digits, ``.`` and ``d`` decimals; ``nan``,
``inf`` and ``-inf`` as Python writes them. The decimals come from rounding the fraction
times ``10**d`` (half to even), so a number whose exact decimal expansion lies within
about 1e-7 of a last-digit tie may end one unit away from Python's (exact) text;
a table that needs more than that should not be printed with a fixed number of decimals.
Rows with a magnitude of 1e15 or more (no integer type holds their digits with ``d``
decimals) are written by Python's formatting instead, so every row has Python's shape;
so is every row when the kernels are not compiled (``SINS_ALIGN_NO_JIT=1``, no numba).
"""
import numpy as np

from ..nav import kernels

#: magnitudes from here on are formatted by Python (the row of them)
_LARGE = 1e15
_NAN, _INF = np.frombuffer(b'nan', np.uint8), np.frombuffer(b'inf', np.uint8)


@kernels.jit
def _put_number(buf, k, x, d, scale):
    """Write ``'%.{d}f' % x`` at ``buf[k:]`` (|x| < 1e15 or not finite); return the end."""
    if x != x:
        for c in _NAN:
            buf[k] = c
            k += 1
        return k
    if np.signbit(x):
        buf[k] = 45                                   # '-'
        k += 1
        x = -x
    if x == np.inf:
        for c in _INF:
            buf[k] = c
            k += 1
        return k
    whole = np.floor(x)
    y = (x - whole) * scale
    r = np.floor(y + 0.5)
    last = r if d > 0 else whole + r                  # the last digit written, unit
    if r - y == 0.5 and last % 2.0 == 1.0:            # a tie: to even, as Python
        r -= 1.0
    # unsigned: division by the constant 10 needs no sign fix-up
    digits = np.uint64(r)
    ip = np.uint64(whole)
    if digits >= np.uint64(scale):
        digits -= np.uint64(scale)
        ip += np.uint64(1)
    ten = np.uint64(10)
    n = 1
    rest = ip
    while rest >= ten:                                # the integer part's digit count
        rest //= ten
        n += 1
    for i in range(n - 1, -1, -1):
        buf[k + i] = np.uint8(48 + ip % ten)
        ip //= ten
    k += n
    if d > 0:
        buf[k] = 46                                   # '.'
        k += 1
        for i in range(d - 1, -1, -1):
            buf[k + i] = np.uint8(48 + digits % ten)
            digits //= ten
        k += d
    return k


@kernels.jit(sig='Tuple((u1[:], i8[:], b1[:]))(f8[:, :], i8[:], i8, i8[:], u1[:, :], i8[:])')
def _format_rows(values, decimals, text_col, text_index, text_bytes, text_len):
    """Kernel of :func:`format_table`: ``(buf, row_end, python_rows)``."""
    n, m = values.shape
    width = 0
    for j in range(m):
        width += 18 + decimals[j]
    width += text_bytes.shape[1] + m + 3
    buf = np.empty(n * width, np.uint8)
    row_end = np.empty(n, np.int64)
    python_rows = np.zeros(n, np.bool_)
    scales = np.empty(m)
    for j in range(m):
        scales[j] = 10.0 ** decimals[j]
    k = 0
    for i in range(n):
        large = False
        for j in range(m):
            if abs(values[i, j]) >= _LARGE and values[i, j] != np.inf \
                    and values[i, j] != -np.inf:
                large = True
        if large:
            python_rows[i] = True
            row_end[i] = k
            continue
        for j in range(m + 1):
            if j > 0:
                buf[k] = 44                           # ','
                k += 1
            if j == text_col:
                s = text_index[i]
                for c in range(text_len[s]):
                    buf[k] = text_bytes[s, c]
                    k += 1
            else:
                jj = j if j < text_col else j - 1
                k = _put_number(buf, k, values[i, jj], decimals[jj], scales[jj])
        buf[k] = 13                                   # '\r\n', as csv.writer ends rows
        buf[k + 1] = 10
        k += 2
        row_end[i] = k
    return buf[:k], row_end, python_rows


@kernels.warms_up
def _first_calls():
    _format_rows(np.zeros((1, 1)), np.ones(1, np.int64), 0, np.zeros(1, np.int64),
                 np.zeros((1, 1), np.uint8), np.zeros(1, np.int64))


def format_table(values, decimals, text, text_col):
    """Return the CSV text (bytes, rows ended by CRLF) of a float table and a text column.

    ``values`` (N, M) float; ``decimals`` (M,) int: the fixed decimals of each column;
    ``text`` (N,) str: the text column (ASCII), written before numeric column
    ``text_col`` (``0 <= text_col <= M``). Fields are separated by ``,``; the text is
    written as is (no quoting: it must not hold ``,``, quotes or line ends).
    """
    values = np.ascontiguousarray(values, dtype=float)
    decimals = np.asarray(decimals, dtype=np.int64)
    if not kernels.COMPILED:
        return _python_rows(values, decimals, text, text_col, np.arange(len(values)))
    names, index = np.unique(np.asarray(text, dtype=str), return_inverse=True)
    encoded = [name.encode('ascii') for name in names]
    width = max((len(e) for e in encoded), default=0)
    text_bytes = np.zeros((max(len(encoded), 1), max(width, 1)), np.uint8)
    for i, e in enumerate(encoded):
        text_bytes[i, :len(e)] = np.frombuffer(e, np.uint8)
    text_len = np.array([len(e) for e in encoded] or [0], np.int64)
    buf, row_end, python_rows = _format_rows(values, decimals, int(text_col),
                                             index.astype(np.int64).ravel(), text_bytes,
                                             text_len)
    pieces, start = [], 0
    for i in np.flatnonzero(python_rows):
        pieces.append(buf[start:row_end[i]].tobytes())
        pieces.append(_python_rows(values, decimals, text, text_col, [i]))
        start = row_end[i]
    pieces.append(buf[start:].tobytes())
    return b''.join(pieces)


def _python_rows(values, decimals, text, text_col, rows, chunk=4096):
    """Return the text of ``rows`` by Python's ``%`` formatting (one per chunk of rows)."""
    fmt = [f'%.{int(d)}f' for d in decimals]
    fmt.insert(int(text_col), '%s')
    row = ','.join(fmt) + '\r\n'
    rows = np.asarray(rows, dtype=np.int64)
    text = np.asarray(text, dtype=object)
    pieces = []
    for k0 in range(0, len(rows), chunk):
        idx = rows[k0:k0 + chunk]
        cells = np.empty((len(idx), values.shape[1] + 1), dtype=object)
        cells[:, :text_col] = values[idx, :text_col]
        cells[:, text_col] = text[idx]
        cells[:, text_col + 1:] = values[idx, text_col:]
        pieces.append(((row * len(idx)) % tuple(cells.ravel().tolist())).encode('ascii'))
    return b''.join(pieces)
