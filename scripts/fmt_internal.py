#!/usr/bin/env python3
"""Formats the items inside the crate's `internal!` invocations, which `cargo fmt` does not look into.

Each `internal! { ... }` block's items are handed to rustfmt (edition 2021, the repository's settings), nested in
wrappers as deep as the block sits, so that lines break at the column they really have; the formatted text goes
back in place. `--check` changes nothing and exits 1 naming each block that would change (`.ci/run` runs it).

usage: scripts/fmt_internal.py [--check] FILE...   (no FILE: every src/**/*.rs holding an invocation)
"""
import pathlib
import re
import subprocess
import sys


def rustfmt(code):
    """The code formatted by rustfmt, or None where it does not parse."""
    r = subprocess.run(["rustfmt", "--edition", "2021", "--emit", "stdout", "-q"],
                       input=code, capture_output=True, text=True)
    return r.stdout if r.returncode == 0 else None


def formatted_blocks(lines, path):
    """The file's lines with every `internal!` block's items formatted, and the blocks that changed."""
    out, changed, i = [], [], 0
    while i < len(lines):
        line = lines[i]
        m = re.match(r"^(\s*)internal! \{$", line)
        if not m:
            out.append(line)
            i += 1
            continue
        indent = m.group(1)
        j = i + 1
        while lines[j] != indent + "}":
            j += 1
        body = lines[i + 1:j]
        inner = indent + "    "
        text = "\n".join(body) + "\n"
        item = re.sub(r"^(\s*(#\[.*\]|//.*)\n)*", "", text)
        is_fn = re.match(r"\s*pub (const |unsafe |async )?fn ", item) is not None
        depth = len(inner) // 4
        openers = ["mod m {"] * (depth - 1) + ["impl W {" if is_fn else "mod m {"]
        result = rustfmt("\n".join(openers) + "\n" + text + "}\n" * depth)
        if result is None:
            sys.exit(f"{path}:{i + 1}: rustfmt could not parse this internal! block")
        wrapped = result.rstrip("\n").split("\n")[depth:-depth]
        new = [l if l.strip() else "" for l in wrapped]
        if new != body:
            changed.append(i + 1)
        out += [line] + new + [lines[j]]
        i = j + 1
    return out, changed


def main():
    args = sys.argv[1:]
    check = "--check" in args
    files = [a for a in args if a != "--check"] or [
        str(p) for p in sorted(pathlib.Path("src").rglob("*.rs")) if "internal! {" in p.read_text()]
    failed = False
    for path in files:
        lines = pathlib.Path(path).read_text().split("\n")
        out, changed = formatted_blocks(lines, path)
        for line in changed:
            print(f"{path}:{line}: internal! block {'not formatted' if check else 'formatted'}")
        if changed and not check:
            pathlib.Path(path).write_text("\n".join(out))
        failed |= bool(changed)
    sys.exit(1 if check and failed else 0)


if __name__ == "__main__":
    main()
