#!/usr/bin/env python3
"""Checks that the tree's references to its math stay inside the tree (scripts/lint.sh refs,
ctest doc_refs).

  doc_refs.py [ROOT]      ROOT: the source tree (default: this script's parent's parent)

Every "math.md §N" (and each further §M in the same run: "math.md §2–§3, §6.1") in any text
file of the tree must name a section that docs/math.md numbers in a heading ("## 2. ...",
"### 6.1 ..."); so must every bare §N inside docs/math.md. No file may cite a contract
document kept outside the tree (the word spelled in FORBIDDEN below, or a path into a folder
beside the tree). Prints one line per problem, path:line: message, and exits 1 if any.
"""
import os
import re
import sys

MATH = os.path.join("docs", "math.md")
# Folders that are not the project's sources: builds, outputs, caches.
SKIP_DIRS = {".git", "out", "__pycache__", ".venv", "node_modules"}
SKIP_EXT = {".png", ".gif", ".jpg", ".npy", ".npz", ".bin", ".obj", ".ply", ".o", ".so", ".a"}
# Spelled in two parts so that this file does not cite what it forbids.
FORBIDDEN = [(re.compile(r"\b" + "SP" + r"EC\b"), "cites the external contract document"),
             (re.compile(r"\.\./" + "shared"), "refers to a folder outside the tree"),
             (re.compile("paper" + r"\.md"), "refers to a document outside the tree")]
HEADING = re.compile(r"^#{2,4} (\d+(?:\.\d+)*)\.? ")
CITATION = re.compile(r"math\.md((?:\s*(?:§\d+(?:\.\d+)*|[,–]|and))+)")
SECTION = re.compile(r"§(\d+(?:\.\d+)*)")


def sections(root):
    with open(os.path.join(root, MATH), encoding="utf-8") as f:
        return {m.group(1) for m in map(HEADING.match, f) if m}


def text_files(root):
    for top, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if d not in SKIP_DIRS and not d.startswith("build"))
        for name in sorted(files):
            if os.path.splitext(name)[1].lower() not in SKIP_EXT:
                yield os.path.join(top, name)


def problems(root):
    known = sections(root)
    if not known:
        yield f"{MATH}:1: no numbered sections found"
    for path in text_files(root):
        rel = os.path.relpath(path, root)
        try:
            with open(path, encoding="utf-8") as f:
                lines = f.read().split("\n")
        except (UnicodeDecodeError, OSError):
            continue  # not a text file
        for number, line in enumerate(lines, 1):
            for pattern, why in FORBIDDEN:
                if pattern.search(line):
                    yield f"{rel}:{number}: {why}: {line.strip()}"
            cited = [s for m in CITATION.finditer(line) for s in SECTION.findall(m.group(1))]
            if rel == MATH:
                cited = SECTION.findall(line)
            for s in cited:
                if s not in known:
                    yield f"{rel}:{number}: math.md has no section §{s}"


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(
        os.path.dirname(os.path.abspath(__file__)))
    found = list(problems(root))
    for p in found:
        print(f"doc_refs: {p}")
    print(f"doc_refs: {len(found)} problem(s)" if found else "doc_refs: every reference resolves")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
