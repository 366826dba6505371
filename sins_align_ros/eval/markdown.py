"""Result pages of the benchmarks: Markdown lines written to a file."""
import os
import platform
from pathlib import Path


def machine_summary():
    """One phrase on the machine: architecture, cores and Python version."""
    return f'{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}'


def write_markdown(path, lines):
    """Write ``lines`` as a Markdown file at ``path`` (creating its folder); return the text."""
    text = '\n'.join(lines) + '\n'
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return text
