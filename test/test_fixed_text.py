"""The compiled fixed-point text of the result CSV gives Python's ``%.{d}f`` text."""
import numpy as np

from sins_align_ros.io import fixed_text


def _table(n=5000, seed=22):
    rng = np.random.default_rng(seed)
    values = np.column_stack([
        rng.normal(size=(n, 3)) * 10.0 ** rng.integers(-12, 13, (n, 3)),   # all magnitudes
        rng.uniform(-1.0, 1.0, (n, 2)),
        np.round(rng.normal(size=n) * 100.0, 3)])                          # short decimals
    values[::97, 0] = np.nan
    values[::101, 1] = np.inf
    values[::103, 2] = -np.inf
    values[::107, 3] = -0.0                   # Python writes '-0'
    values[::109, 4] = -1e-13                 # rounds to zero, keeps its sign
    values[5, 0], values[7, 1] = 1e16, -3e20  # past the kernel's range: Python's rows
    values[9, 0], values[11, 0] = 0.9999999999999, -0.99999999995    # carries into ints
    values[13, 3], values[15, 3] = 2.5, -3.5   # exact ties at d = 0: to even, as Python
    text = rng.choice(['waiting', 'coarse', 'fine', 'aligned'], n)
    return values, np.array([9, 12, 4, 0, 10, 6]), text


def test_the_text_is_pythons_to_the_byte():
    values, decimals, text = _table()
    for text_col in (0, 3, 6):
        got = fixed_text.format_table(values, decimals, text, text_col)
        fmt = [f'%.{d}f' for d in decimals]
        fmt.insert(text_col, '%s')
        want = ''.join(','.join(fmt) % tuple(
            [*row[:text_col], name, *row[text_col:]]) + '\r\n'
            for row, name in zip(values.tolist(), text)).encode()
        assert got == want


def test_an_empty_table_is_empty_text():
    assert fixed_text.format_table(np.empty((0, 2)), [3, 3], [], 1) == b''


def _python_text(values, decimals, text, text_col):
    fmt = [f'%.{d}f' for d in decimals]
    fmt.insert(text_col, '%s')
    return ''.join(','.join(fmt) % tuple([*row[:text_col], name, *row[text_col:]]) + '\r\n'
                   for row, name in zip(values.tolist(), text)).encode()


def test_pieces_across_kernel_chunks_and_a_file_give_the_same_text(monkeypatch, tmp_path):
    """Formatted a few rows per kernel call (Python's rows inside and at chunk edges), the
    pieces joined and written to a file are the whole table's text; the text column in
    runs and as a list of str."""
    values, decimals, text = _table(n=300)
    text = np.repeat(['coarse', 'fine', 'aligned', 'fine'], [100, 50, 120, 30])
    values[6, 0] = 2e15                        # Python's row at the end of a chunk of 7
    want = _python_text(values, decimals, text, 2)
    for rows in (7, 4096):
        monkeypatch.setattr(fixed_text, 'CHUNK_ROWS', rows)
        assert fixed_text.format_table(values, decimals, list(text), 2) == want
        with open(tmp_path / 'x.csv', 'wb') as f:
            fixed_text.write_table(f, values, decimals, text.astype(object), 2)
        assert (tmp_path / 'x.csv').read_bytes() == want
