#!/usr/bin/env python3
"""Judges the findings of scripts/lint.sh against the allow-list (.lint-allow).

  lint_findings.py ROOT ALLOW tidy          clang-tidy's output on stdin
  lint_findings.py ROOT ALLOW size MAX      `wc -l` lines on stdin
  lint_findings.py ROOT ALLOW functions MAX paths of OpenCL C and Python files on stdin

tidy: every finding in a file of the source tree fails, except readability-function-size on a
function that ALLOW lists.
size: a file over MAX lines fails unless ALLOW lists it.
functions: what clang-tidy's function-size rule does for C++, for the kernels and the Python: a
function whose body is over MAX lines fails unless ALLOW lists it.
An ALLOW entry that no longer matches (a function now short enough, a file now short enough)
fails too. Exit status 1 on failure.
"""
import ast
import os
import re
import sys

FINDING = re.compile(r"^(/[^:]+):(\d+):(\d+): (?:warning|error): (.*) \[([\w.,-]+)\]$")
LINES_NOTE = re.compile(r"^/[^:]+:\d+:\d+: note: (\d+) lines including")
FUNCTION = re.compile(r"function '([^']+)' exceeds")
TEST = re.compile(r"\b(?:TEST|TEST_F|TEST_P|TYPED_TEST)\(\s*(\w+)\s*,\s*(\w+)\s*\)")


def read_allow(path):
    entries = {}
    for number, raw in enumerate(open(path, encoding="utf-8"), 1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        body, _, reason = line.partition("#")
        words = body.split()
        ok = reason.strip() and (
            (len(words) == 3 and words[0] == "function") or (len(words) == 2 and words[0] == "file"))
        if not ok:
            sys.exit(f"lint: {path}:{number}: expected 'function <path> <name>  # <reason>' or "
                     f"'file <path>  # <reason>', got: {line}")
        entries[tuple(words)] = reason.strip()
    return entries


def function_name(root, rel, line, name):
    """Suite.Test for a GoogleTest body (its TEST(...) line), else the name clang-tidy gives."""
    if name != "TestBody":
        return name
    try:
        text = open(os.path.join(root, rel), encoding="utf-8").read().splitlines()[line - 1]
    except (OSError, IndexError):
        return name
    m = TEST.search(text)
    return f"{m.group(1)}.{m.group(2)}" if m else name


def tidy(root, allow):
    units = set(filter(None, os.environ.get("LINT_UNITS", "").split("\n")))
    seen, failures, long_functions = set(), [], set()
    last = None
    for raw in sys.stdin:
        line = raw.rstrip("\n")
        note = LINES_NOTE.match(line)
        if note and last:
            last[1] = f"{last[1]} ({note.group(1)} lines)"
            continue
        m = FINDING.match(line)
        if not m:
            continue
        path, row, col, message, check = m.groups()
        check = check.replace(",-warnings-as-errors", "")
        rel = os.path.relpath(path, root)
        last = None
        if rel.startswith("..") or rel.startswith("build"):
            continue
        key = (rel, row, col, check)
        if key in seen:
            continue
        seen.add(key)
        if check == "readability-function-size":
            f = FUNCTION.search(message)
            name = function_name(root, rel, int(row), f.group(1) if f else "?")
            long_functions.add((rel, name))
            if ("function", rel, name) in allow:
                continue
            message = f"function {name} is over 60 lines; shorten it or list it in .lint-allow"
        last = [f"{rel}:{row}:{col}", message, check]
        failures.append(last)
    for entry in sorted(allow):
        if entry[0] == "function" and entry[1] in units and entry[1:] not in long_functions:
            failures.append([entry[1], f"the .lint-allow entry for {entry[2]} is no longer "
                             "needed (remove it)", "lint-allow"])
    for where, message, check in failures:
        print(f"{where}: {message} [{check}]")
    print(f"lint: tidy: {len(failures)} findings, {len(long_functions)} functions over 60 lines "
          f"({sum(1 for e in allow if e[0] == 'function')} allowed)")
    return 1 if failures else 0


def size(root, allow, limit):
    failures = 0
    lengths = {}
    for raw in sys.stdin:
        count, path = raw.split(None, 1)
        lengths[path.strip()] = int(count)
    for path, count in sorted(lengths.items()):
        if count > limit and ("file", path) not in allow:
            print(f"{path}: {count} lines, over {limit}; split it or list it in .lint-allow")
            failures += 1
    for entry in sorted(allow):
        if entry[0] == "file" and lengths.get(entry[1], 0) <= limit:
            print(f"{entry[1]}: the .lint-allow entry is no longer needed (remove it)")
            failures += 1
    over = sum(1 for c in lengths.values() if c > limit)
    print(f"lint: size: {len(lengths)} files, {over} over {limit} lines "
          f"({sum(1 for e in allow if e[0] == 'file')} allowed), {failures} failures")
    return 1 if failures else 0


def python_functions(text):
    """(name, body lines) of every function of a Python source."""
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node.name, node.end_lineno - node.body[0].lineno + 1


OPENCL_NOISE = re.compile(r"//[^\n]*|/\*.*?\*/|\"(?:\\.|[^\"\\])*\"|'(?:\\.|[^'\\])*'", re.S)
OPENCL_NAME = re.compile(r"(\w+)\s*\([^()]*(?:\([^()]*\)[^()]*)*\)\s*$")


def opencl_functions(text):
    """(name, body lines) of every function of an OpenCL C source: a brace at file scope after
    a parameter list opens one. Comments, literals and preprocessor lines are left out."""
    text = OPENCL_NOISE.sub(lambda m: "\n" * m.group(0).count("\n"), text)
    lines = text.split("\n")
    depth, head, start, name = 0, "", 0, None
    in_directive = False
    for number, line in enumerate(lines, 1):
        directive = in_directive or line.lstrip().startswith("#")
        in_directive = directive and line.rstrip().endswith("\\")
        if directive:
            continue
        for i, ch in enumerate(line):
            if ch == "{":
                if depth == 0:
                    m = OPENCL_NAME.search(head + line[:i])
                    name, start = (m.group(1) if m else None), number
                depth += 1
            elif ch == "}":
                depth -= 1
                if depth == 0 and name:
                    yield name, number - start - 1
                    name = None
            elif ch == ";" and depth == 0:
                head = ""
        head = "" if depth else (head + " " + line)[-2000:]


def functions(root, allow, limit):
    failures, long_functions, counted = 0, set(), set()
    for raw in sys.stdin:
        rel = raw.strip()
        counted.add(rel)
        text = open(os.path.join(root, rel), encoding="utf-8").read()
        found = python_functions(text) if rel.endswith(".py") else opencl_functions(text)
        for name, lines in found:
            if lines <= limit:
                continue
            long_functions.add((rel, name))
            if ("function", rel, name) not in allow:
                print(f"{rel}: function {name} is {lines} lines, over {limit}; shorten it or "
                      "list it in .lint-allow")
                failures += 1
    for entry in sorted(allow):
        if entry[0] == "function" and entry[1] in counted and entry[1:] not in long_functions:
            print(f"{entry[1]}: the .lint-allow entry for {entry[2]} is no longer needed "
                  "(remove it)")
            failures += 1
    print(f"lint: functions: {len(counted)} kernel and Python files, {len(long_functions)} "
          f"functions over {limit} lines, {failures} failures")
    return 1 if failures else 0


def main():
    root, allow_path, mode = sys.argv[1:4]
    allow = read_allow(allow_path) if os.path.exists(allow_path) else {}
    if mode == "tidy":
        return tidy(root, allow)
    if mode == "functions":
        return functions(root, allow, int(sys.argv[4]))
    return size(root, allow, int(sys.argv[4]))


if __name__ == "__main__":
    sys.exit(main())
