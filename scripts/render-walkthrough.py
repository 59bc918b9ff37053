#!/usr/bin/env python3
"""Render docs/model-error-walkthrough.md from the real output of the sample.

    bash samples/model-error-loop.sh > /tmp/loop.txt
    ROUTE=analyzer bash tests/support/loop_trial.sh 3 > /tmp/trial.txt   # optional
    python3 scripts/render-walkthrough.py /tmp/loop.txt [--trial /tmp/trial.txt] \
        > docs/model-error-walkthrough.md

The template (docs/dev/walkthrough.template.md) holds the prose; {{N}} stands for the
N-th command of the sample's output (0-based, a command starts with '$ '), printed as
an indented block; {{N:head=K}} for its first K lines; {{TRIAL}} for the trial's
summary (or a note that it was not run).  The numbers in the prose are checked by
hand against the output: rerender and reread when the output changes.
"""
import argparse
import pathlib
import re
import sys


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("output", help="the printed output of samples/model-error-loop.sh")
    ap.add_argument("--trial", help="the printed output of tests/support/loop_trial.sh")
    ap.add_argument("--template", default=str(pathlib.Path(__file__).resolve().parent.parent
                                              / "docs/dev/walkthrough.template.md"))
    a = ap.parse_args()
    text = pathlib.Path(a.output).read_text()
    blocks = [b.rstrip("\n") for b in re.split(r"\n(?=\$ )", text.strip("\n"))]
    if not blocks or not blocks[0].startswith("$ "):
        print(f"render-walkthrough: {a.output}: no '$ ' command found; give the sample's output", file=sys.stderr)
        return 2

    def block(m: re.Match) -> str:
        n = int(m.group(1))
        if n >= len(blocks):
            raise SystemExit(f"render-walkthrough: the template asks for command {n}; "
                             f"{a.output} has {len(blocks)} (rerun the sample)")
        lines = blocks[n].splitlines()
        if m.group(2):
            lines = lines[: int(m.group(2))] + ["    ..."]
        return "\n".join("    " + line if line else "" for line in lines)

    out = re.sub(r"\{\{(\d+)(?::head=(\d+))?\}\}", block, pathlib.Path(a.template).read_text())
    trial = "(the trial was not run for this rendering)"
    if a.trial:
        trial = "\n".join("    " + line for line in pathlib.Path(a.trial).read_text().strip("\n").splitlines())
    out = out.replace("{{TRIAL}}", trial)
    sys.stdout.write(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
