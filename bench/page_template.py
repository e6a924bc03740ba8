"""The prose of docs/benchmarks.md: the blocks of bench/report_template.md, filled in.

A block runs from its `<!-- name -->` line to the next such line; its $placeholders are
string.Template's. block() gives a block's lines, text() a one-line block as a string."""
import os
import re
import string

PATH = os.path.join(os.path.dirname(os.path.abspath(__file__)), "report_template.md")
MARKER = re.compile(r"^<!-- (.+) -->$")


def read_blocks(path=PATH):
    """{name: text} in the file's order; the text before the first marker is a comment."""
    blocks, name, lines = {}, None, []
    with open(path, encoding="utf-8") as f:
        raw = f.read()
    for line in raw[:-1].split("\n") if raw.endswith("\n") else raw.split("\n"):
        m = MARKER.match(line)
        if m:
            if name is not None:
                blocks[name] = "\n".join(lines)
            name, lines = m.group(1), []
        elif name is not None:
            lines.append(line)
    if name is not None:
        blocks[name] = "\n".join(lines)
    return blocks


BLOCKS = read_blocks()


def text(name, **values):
    """Block `name` with its placeholders filled, as one string."""
    return string.Template(BLOCKS[name]).substitute(values)


def block(name, **values):
    """Block `name` with its placeholders filled, as the page's lines."""
    return text(name, **values).split("\n")


def named(prefix):
    """(name less prefix, text) of the blocks whose names start with `prefix`, in file order."""
    return [(n[len(prefix):], b) for n, b in BLOCKS.items() if n.startswith(prefix)]


def table(header, rows):
    """A Markdown table, as one string."""
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(out)
