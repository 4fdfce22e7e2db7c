#!/usr/bin/env python3
"""Runs the worked example of docs/post-processing.md and checks that its snippets print what
the page says they print.

The page's figures are pasted from real runs; when the physics or the output changes, they go
stale without anyone noticing (twice before this check existed). A run is bitwise the same for
any thread count, so the printed figures can be compared exactly.

What is checked:
- every ```python block followed by a ```text block: run, its output equal to the text;
- every `$ ` command of a ```console block that runs a script the page defines (a ```python
  block introduced by a line naming `NAME.py`) or the `cut ... | tail` of the CSV section: run,
  its output equal to the lines under it. A block with an elision mark (…) is not compared.

What is not: the ParaView script and the screenshot (scripts/check_output.sh runs ParaView's
readers), `watch.py`'s output (taken while a run was writing the file), and scripts that need
matplotlib when it is missing (said on stderr).

The page's paths are mapped: /work/main to this checkout, /tmp/docrun to the work folder, and
files the page writes into docs/images to the work folder, so that the check never rewrites the
page's images.

Usage: python3 scripts/check_docs.py [WORK_DIR]     (exit status 1 on any mismatch)
"""
import importlib.util
import pathlib
import re
import shlex
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
PAGE = ROOT / "docs" / "post-processing.md"
SKIPPED_SCRIPTS = {"watch.py", "paraview_track.py"}


def blocks(text):
    """The page's fenced blocks as (language, body, line of the opening fence, prose before)."""
    found, lines = [], text.split("\n")
    i, prose = 0, []
    while i < len(lines):
        m = re.match(r"^```(\w*)\s*$", lines[i])
        if m:
            start = i
            i += 1
            body = []
            while not lines[i].startswith("```"):
                body.append(lines[i])
                i += 1
            found.append((m.group(1), "\n".join(body) + "\n", start + 1, "\n".join(prose)))
            prose = []
        else:
            prose.append(lines[i])
        i += 1
    return found


def mapped(text, work):
    """The page's paths mapped to this checkout and the work folder."""
    return (
        text.replace("/work/main/docs/images/", f"{work}/")
        .replace("/tmp/docrun", str(work))
        .replace("/work/main", str(ROOT))
    )


def run(command, work, stdin=None):
    result = subprocess.run(
        command, shell=True, cwd=work, input=stdin, capture_output=True, text=True
    )
    return result.returncode, result.stdout, result.stderr


def main():
    work = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else tempfile.mkdtemp()).resolve()
    work.mkdir(parents=True, exist_ok=True)
    page = PAGE.read_text(encoding="utf-8")
    found = blocks(page)
    has_matplotlib = importlib.util.find_spec("matplotlib") is not None
    passed, failed, skipped = 0, 0, 0

    def fail(line, message):
        nonlocal failed
        failed += 1
        print(f"FAIL post-processing.md:{line}: {message}")

    # The example run: the page's first ```sh block, in the work folder.
    _, setup, line, _ = found[0]
    commands = [c for c in mapped(setup, work).splitlines() if c and not c.startswith("cd ")]
    commands = [c for c in commands if not c.startswith("mkdir ")]
    subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)
    for command in commands:
        code, _, err = run(command, work)
        if code != 0:
            fail(line, f"the example run failed: {command}\n{err}")
            return 1

    scripts = {}
    for k, (language, body, line, prose) in enumerate(found):
        nxt = found[k + 1] if k + 1 < len(found) else None
        if language == "python":
            named = re.findall(r"`(\w+\.py)`", prose.strip().split("\n\n")[-1])
            if named:
                scripts[named[-1]] = body
                (work / named[-1]).write_text(mapped(body, work), encoding="utf-8")
            if nxt and nxt[0] == "text" and not nxt[3].strip():
                needs_matplotlib = "matplotlib" in body
                if needs_matplotlib and not has_matplotlib:
                    skipped += 1
                    continue
                code, out, err = run("python3 -", work, stdin=mapped(body, work))
                if code != 0:
                    fail(line, f"the snippet failed:\n{err}")
                elif out != mapped(nxt[1], work):
                    fail(line, f"printed\n{out}instead of\n{mapped(nxt[1], work)}")
                else:
                    passed += 1
        elif language == "console":
            if "…" in body:
                continue
            entries, current = [], None
            for text in body.splitlines():
                if text.startswith("$ "):
                    current = [text[2:], []]
                    entries.append(current)
                elif current is not None:
                    current[1].append(text)
            for command, expected in entries:
                words = shlex.split(command.split("|")[0])
                script = next((w for w in words if w.endswith(".py")), None)
                name = script and pathlib.Path(script).name
                if name in SKIPPED_SCRIPTS:
                    skipped += 1
                    continue
                if name and name not in scripts:
                    continue  # a script of the repository, checked elsewhere
                if not name and not command.startswith("cut "):
                    continue
                if name and "matplotlib" in scripts[name] and not has_matplotlib:
                    print(f"check_docs: matplotlib missing, {name} not run", file=sys.stderr)
                    skipped += 1
                    continue
                code, out, err = run(mapped(command, work), work)
                want = mapped("\n".join(expected) + "\n", work)
                if code != 0:
                    fail(line, f"`{command}` failed:\n{err}")
                elif out != want:
                    fail(line, f"`{command}` printed\n{out}instead of\n{want}")
                else:
                    passed += 1
    print(f"check_docs: {passed} passed, {failed} failed, {skipped} skipped ({work})")
    return 1 if failed or passed == 0 else 0


if __name__ == "__main__":
    sys.exit(main())
