"""Fixed-point text of a table of floats and one text column, compiled (the result CSV).

Python's ``%`` formatting of the 1.6 million numbers of a 1200 s, 100 Hz replay's CSV
took 0.3-0.4 s, more than the whole fine alignment of some filters; :func:`format_table`
writes the same text from a compiled kernel in about 60 ms (:func:`write_table` straight
into the file, a few thousand rows at a time).

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

from .. import compiled

#: magnitudes from here on are formatted by Python (the row of them)
_LARGE = 1e15
_NAN, _INF = np.frombuffer(b'nan', np.uint8), np.frombuffer(b'inf', np.uint8)
#: the ASCII digits of 00, 01, ..., 99 (200 bytes)
_PAIRS = np.frombuffer(b''.join(b'%02d' % i for i in range(100)), np.uint8)
#: 10**i as uint64, i = 0..19
_POW10 = np.array([10 ** i for i in range(20)], np.uint64)


@compiled.jit(sig='Tuple((u1[:], i8[:], b1[:]))(f8[:, :], i8[:], i8, i8[:], u1[:, :], i8[:])')
def _format_rows(values, decimals, text_col, text_index, text_bytes, text_len):
    """Kernel of :func:`format_table`: ``(buf, row_end, python_rows)``.

    Each number is written in the row loop itself (a helper function given ``buf`` cost a
    third of the kernel's time in its calls), its digits two at a time from
    :data:`_PAIRS`.
    """
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
    hundred = np.uint64(100)
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
                continue
            # '%.{d}f' % x at buf[k:] (|x| < 1e15 or not finite)
            jj = j if j < text_col else j - 1
            x, d, scale = values[i, jj], decimals[jj], scales[jj]
            if x != x:
                for c in range(3):
                    buf[k + c] = _NAN[c]
                k += 3
                continue
            if np.signbit(x):
                buf[k] = 45                           # '-'
                k += 1
                x = -x
            if x == np.inf:
                for c in range(3):
                    buf[k + c] = _INF[c]
                k += 3
                continue
            whole = np.floor(x)
            y = (x - whole) * scale
            r = np.floor(y + 0.5)
            last = r if d > 0 else whole + r          # the last digit written, unit
            if r - y == 0.5 and last % 2.0 == 1.0:    # a tie: to even, as Python
                r -= 1.0
            # unsigned: division by a constant needs no sign fix-up
            digits = np.uint64(r)
            ip = np.uint64(whole)
            if digits >= np.uint64(scale):
                digits -= np.uint64(scale)
                ip += np.uint64(1)
            n_ip = 1                                  # the integer part's digit count
            while n_ip < 20 and ip >= _POW10[n_ip]:
                n_ip += 1
            for part in range(2 if d > 0 else 1):     # the integer part, then the decimals
                if part == 0:
                    v, left, e = ip, n_ip, k + n_ip
                else:
                    buf[k + n_ip] = 46                # '.'
                    v, left, e = digits, d, k + n_ip + 1 + d
                while left >= 2:                      # backwards from e, two at a time
                    q = v // hundred
                    two = 2 * np.int64(v - q * hundred)
                    e -= 2
                    buf[e] = _PAIRS[two]
                    buf[e + 1] = _PAIRS[two + 1]
                    v = q
                    left -= 2
                if left == 1:
                    buf[e - 1] = np.uint8(48 + v)
            k += n_ip + (1 + d if d > 0 else 0)
        buf[k] = 13                                   # '\r\n', as csv.writer ends rows
        buf[k + 1] = 10
        k += 2
        row_end[i] = k
    return buf[:k], row_end, python_rows


@compiled.warms_up
def _first_calls():
    _format_rows(np.zeros((1, 1)), np.ones(1, np.int64), 0, np.zeros(1, np.int64),
                 np.zeros((1, 1), np.uint8), np.zeros(1, np.int64))


#: rows formatted per kernel call (each a fresh buffer of about 2 MB: yielded pieces stay valid)
CHUNK_ROWS = 4096


def format_table(values, decimals, text, text_col):
    """Return the CSV text (bytes, rows ended by CRLF) of a float table and a text column.

    ``values`` (N, M) float; ``decimals`` (M,) int: the fixed decimals of each column;
    ``text`` (N,) str: the text column (ASCII), written before numeric column
    ``text_col`` (``0 <= text_col <= M``). Fields are separated by ``,``; the text is
    written as is (no quoting: it must not hold ``,``, quotes or line ends).
    """
    return b''.join(table_pieces(values, decimals, text, text_col))


def write_table(f, values, decimals, text, text_col):
    """Write :func:`format_table`'s text to the binary file ``f``, piece by piece.

    No text of the whole table is held: each piece goes to ``f`` as it is made (the text
    of a 120 000-row result CSV is 27 MB, and fresh memory of that size costs as much
    as formatting it).
    """
    for piece in table_pieces(values, decimals, text, text_col):
        f.write(piece)


def table_pieces(values, decimals, text, text_col):
    """Yield :func:`format_table`'s text in order, in pieces (bytes-like: bytes or uint8 arrays).

    The compiled kernel formats :data:`CHUNK_ROWS` rows at a time; rows it leaves to
    Python (magnitudes of 1e15 or more) are Python's ``%`` text.
    """
    values = np.ascontiguousarray(values, dtype=float)
    decimals = np.asarray(decimals, dtype=np.int64)
    if not compiled.COMPILED:
        yield _python_rows(values, decimals, text, text_col, np.arange(len(values)))
        return
    names, index = _factorise_runs(text)
    encoded = [name.encode('ascii') for name in names]
    width = max((len(e) for e in encoded), default=0)
    text_bytes = np.zeros((max(len(encoded), 1), max(width, 1)), np.uint8)
    for i, e in enumerate(encoded):
        text_bytes[i, :len(e)] = np.frombuffer(e, np.uint8)
    text_len = np.array([len(e) for e in encoded] or [0], np.int64)
    for r0 in range(0, len(values), CHUNK_ROWS):
        r1 = min(r0 + CHUNK_ROWS, len(values))
        buf, row_end, python_rows = _format_rows(values[r0:r1], decimals, int(text_col),
                                                 index[r0:r1], text_bytes, text_len)
        start = 0
        for i in np.flatnonzero(python_rows).tolist():
            yield buf[start:row_end[i]]
            yield _python_rows(values, decimals, text, text_col, [r0 + i])
            start = row_end[i]
        yield buf[start:]


def _factorise_runs(text):
    """Return ``(names, index)``: the distinct strings of ``text`` (N,) and each row's (int64).

    Found run by run: a result CSV's text column (the phase) holds a few values in long
    runs, so comparing neighbours and naming each run costs far less than sorting the
    column's strings (``np.unique``: 13 ms of a 120 000-row CSV).
    """
    text = np.asarray(text)
    if text.dtype.kind not in 'UO':
        text = text.astype(str)
    n = len(text)
    if n == 0:
        return [], np.zeros(0, np.int64)
    starts = np.flatnonzero(text[1:] != text[:-1]) + 1
    lengths = np.diff(starts, prepend=0, append=n)
    codes = {}
    run_codes = [codes.setdefault(str(name), len(codes))
                 for name in text[np.r_[0, starts]].tolist()]
    return list(codes), np.repeat(np.array(run_codes, np.int64), lengths)


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
