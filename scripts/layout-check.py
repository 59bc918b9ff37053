#!/usr/bin/env python3
"""The layout rule of issue 26 (docs/architecture.md, "Size"): no file of idlib/ over
MAX_FILE lines and no function of idlib/, cli/ or formats/ over MAX_FUNCTION lines.

Usage: scripts/layout-check.py [ROOT]   (exit 1 and one line per breach when broken)

A function is a brace block opened at namespace scope (or in a class at namespace
scope: an inline member) whose head is not a namespace, class, struct, union or enum;
its length counts its lines from the head's brace to the closing one.  Comments and
string literals are blanked first, so braces in them do not count.
"""
import os
import re
import sys

MAX_FILE = 800  # "no file of idlib over ~800 lines": the tilde is this script's 2 % slack
FILE_SLACK = 16
MAX_FUNCTION = 150

TYPE_HEAD = re.compile(r"\b(namespace|class|struct|union|enum)\b[^;{()]*$")
# a head that ends a parameter list with qualifiers or a trailing return type
FUNCTION_TAIL = re.compile(r"\)\s*(const|noexcept|override|final|->[^{]*)[\s\w:<>,&*]*$")


def blank(text):
    """Comments and string/char literals replaced by spaces (newlines kept)."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif text.startswith('R"', i):
            m = re.match(r'R"([^(\s]*)\(', text[i:])
            if not m:
                out.append(c)
                i += 1
                continue
            end = ")" + m.group(1) + '"'
            j = text.find(end, i + m.end())
            j = n if j < 0 else j + len(end)
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            j = min(j + 1, n)
            out.append(" " * (j - i))
            i = j
        else:
            out.append(c)
            i += 1
    return "".join(out)


def functions(path):
    """(first line, length, head) of every function body in a file."""
    text = blank(open(path, encoding="utf-8", errors="replace").read())
    stack = []  # (kind, line, head)
    found = []
    line = 1
    start = 0
    for i, c in enumerate(text):
        if c == "\n":
            line += 1
        elif c == "{":
            head = text[start:i]
            head = head[head.rfind(";") + 1:] if ";" in head else head
            head = " ".join(head.split())
            enclosing_types = all(k in ("ns", "type") for k, _, _ in stack)
            if TYPE_HEAD.search(head) or head.startswith("extern"):
                kind = "ns" if "namespace" in head or head.startswith("extern") else "type"
            elif enclosing_types and (head.endswith(")") or FUNCTION_TAIL.search(head)):
                kind = "fn"
            else:
                kind = "block"
            stack.append((kind, line, head))
            start = i + 1
        elif c == "}":
            if stack:
                kind, first, head = stack.pop()
                if kind == "fn":
                    found.append((first, line - first, head))
            start = i + 1
        elif c == ";":
            start = i + 1
    return found


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..")
    breaches = []
    for top in ("idlib", "cli", "formats"):
        for dirpath, _, names in os.walk(os.path.join(root, top)):
            for name in sorted(names):
                if not name.endswith((".cc", ".h")):
                    continue
                path = os.path.join(dirpath, name)
                rel = os.path.relpath(path, root)
                lines = open(path, encoding="utf-8", errors="replace").read().count("\n")
                if top == "idlib" and lines > MAX_FILE + FILE_SLACK:
                    breaches.append(f"{rel}: {lines} lines (idlib's files: at most ~{MAX_FILE})")
                for first, length, head in functions(path):
                    if length > MAX_FUNCTION:
                        breaches.append(f"{rel}:{first}: a function of {length} lines (at most {MAX_FUNCTION}): "
                                        f"{head[:70]}")
    for b in breaches:
        print(b)
    if breaches:
        print(f"layout-check: {len(breaches)} breach(es) of the layout rule (docs/architecture.md, \"Size\")")
        return 1
    print("layout-check: every idlib file within ~%d lines, every function within %d" % (MAX_FILE, MAX_FUNCTION))
    return 0


if __name__ == "__main__":
    sys.exit(main())
