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


def page_head(title, command, *paragraphs):
    """Return the first lines of a result page: its title, the command and machine, text.

    ``command``: the command line that wrote the page (shown as code); each of
    ``paragraphs`` follows as one paragraph.
    """
    lines = [f'# {title}', '', f'Command: `{command}` on {machine_summary()}.', '']
    for text in paragraphs:
        lines += [text, '']
    return lines
