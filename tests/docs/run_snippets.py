#!/usr/bin/env python3
"""Runs the ```python and ```sh blocks of a Markdown file, each in a fresh temporary directory.

Usage: run_snippets.py FILE.md

Python blocks run with this interpreter (the module is found through PYTHONPATH); shell blocks
run under `bash -euo pipefail` with the CLI named by RPYFMM_CLI on PATH as `rpyfmm`. Blocks
fenced as ```bash or ```cpp are not run (the quick-start commands install packages and build).
Exits non-zero, naming the block and its first line in the file, when any block fails.
"""
import os
import re
import subprocess
import sys
import tempfile
import time

FENCE = re.compile(r"^```(\w*)\s*$")
RUN = {"python": None, "sh": None}


def blocks(path):
    """(language, first line number, text) of every fenced block of a language in RUN."""
    lang, start, lines = None, 0, []
    with open(path, encoding="utf-8") as f:
        for number, line in enumerate(f, 1):
            m = FENCE.match(line.rstrip("\n"))
            if m and lang is None:
                lang, start, lines = m.group(1), number + 1, []
            elif m:
                if lang in RUN:
                    yield lang, start, "".join(lines)
                lang = None
            elif lang is not None:
                lines.append(line)


def command(lang, text, bin_dir):
    if lang == "python":
        return [sys.executable, "-c", text], None
    env = dict(os.environ, PATH=bin_dir + os.pathsep + os.environ.get("PATH", ""))
    return ["bash", "-euo", "pipefail", "-c", text], env


def main():
    path = sys.argv[1]
    cli = os.environ.get("RPYFMM_CLI")
    if not cli:
        sys.exit("RPYFMM_CLI is not set (the rpyfmm binary of this build)")
    failures, count = 0, 0
    with tempfile.TemporaryDirectory() as bin_dir:
        os.symlink(os.path.abspath(cli), os.path.join(bin_dir, "rpyfmm"))
        for lang, line, text in blocks(path):
            count += 1
            with tempfile.TemporaryDirectory() as work:
                args, env = command(lang, text, bin_dir)
                start = time.time()
                result = subprocess.run(args, cwd=work, env=env, capture_output=True, text=True, timeout=100)
                took = time.time() - start
            status = "ok" if result.returncode == 0 else "FAILED (exit %d)" % result.returncode
            print("%s:%d: %s block %s in %.1f s" % (path, line, lang, status, took))
            if result.returncode != 0:
                failures += 1
                sys.stdout.write(result.stdout[-4000:])
                sys.stdout.write(result.stderr[-4000:])
    if count == 0:
        sys.exit("%s: no ```python or ```sh blocks found" % path)
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
