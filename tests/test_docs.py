"""The documentation says what is true: the mkdocs site builds with --strict (no broken link or anchor, no
page outside the nav), the README stays short and keeps CI's test command, and every shell command shown
in README.md and docs/*.md runs.

Commands: a fenced block whose first command starts with `millpost` (or `$ millpost`, then the output it
prints) is run in a folder of its own per page, holding a copy of sample_jobs/, in the page's order, and
must exit 0. HTML comments just before a block mark what the test does with it (docs/testing.md):
`<!-- not run: REASON -->` skips it (hardware), `<!-- exit: N -->` expects exit N, `<!-- run: python -->`
runs a Python block, `<!-- file: NAME -->` writes the block to NAME, `<!-- test setup: NAME -->` runs
SETUPS[NAME] first (inputs a reader would have measured)."""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
README = ROOT / "README.md"
PAGES = [README, *sorted(DOCS.glob("*.md"))]
TIMEOUT_S = 600


# --- reading the Markdown -------------------------------------------------------------------------------
@dataclass
class Block:
    page: Path
    line: int                                   # the opening fence's line (1-based)
    lang: str
    text: str
    markers: dict[str, str] = field(default_factory=dict)

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"

    def commands(self) -> list[tuple[str, list[str]]]:
        """(command, the output lines shown after it). Lines ending in a backslash continue; in a block with
        `$ ` prompts only the prompted lines are commands, the lines after each its output."""
        lines: list[str] = []
        for raw in self.text.splitlines():
            if lines and lines[-1].endswith("\\"):
                lines[-1] = lines[-1][:-1].rstrip() + " " + raw.strip()
            else:
                lines.append(raw)
        if any(l.startswith("$ ") for l in lines):
            out: list[tuple[str, list[str]]] = []
            for l in lines:
                if l.startswith("$ "):
                    out.append((l[2:].strip(), []))
                elif out:
                    out[-1][1].append(l)
            return out
        return [(l.strip(), []) for l in lines if l.strip() and not l.lstrip().startswith("#")]

    def is_millpost(self) -> bool:
        cmds = self.commands()
        return bool(cmds) and cmds[0][0].split()[0] == "millpost"


MARKER = re.compile(r"<!--\s*([\w ]+?)\s*(?::\s*(.*?))?\s*-->\s*$")


def blocks(page: Path) -> list[Block]:
    """The fenced blocks of a page, each with the marker comments on the lines just before its fence."""
    lines = page.read_text().splitlines()
    out, i = [], 0
    while i < len(lines):
        m = re.match(r"^```(\w*)\s*$", lines[i])
        if not m:
            i += 1
            continue
        start = i
        j = i + 1
        while j < len(lines) and not lines[j].startswith("```"):
            j += 1
        markers: dict[str, str] = {}
        k = start - 1
        while k >= 0 and (mk := MARKER.match(lines[k].strip())):
            markers[mk.group(1).strip()] = (mk.group(2) or "").strip()
            k -= 1
        out.append(Block(page, start + 1, m.group(1), "\n".join(lines[start + 1:j]) + "\n", markers))
        i = j + 1
    return out


# --- what the test provides that a reader would have ----------------------------------------------------
def _my_machine(folder: Path) -> None:
    """The reader's own machine file: vmc-small with the no-load power and current a spindle draws."""
    from millpost.config import resolve
    text = resolve("machines", "vmc-small").read_text().replace(
        "[spindle]", "[spindle]\nidle_rpm = [2000, 10000]\nidle_power_W = [80, 300]\n", 1)
    (folder / "my-mill.toml").write_text(text.replace('name = "vmc-small"', 'name = "my-mill"', 1))


def _discover_run(folder: Path) -> None:
    """The worked example's job and measured log (tests/discover_runs.py, seed 0, deflection, 3 % noise)."""
    from discover_runs import make_run
    from millpost.measure import write_log
    run = make_run(folder, 0, "deflection", noise=0.03)
    write_log(folder / "log.csv", run.log)


SETUPS = {"my_machine": _my_machine, "discover_run": _discover_run}


# --- running --------------------------------------------------------------------------------------------
def _millpost() -> list[str]:
    exe = Path(sys.executable).with_name("millpost")
    return [str(exe)] if exe.exists() else [sys.executable, "-c", "import sys; from millpost.cli import run; sys.exit(run())"]


def _env() -> dict[str, str]:
    env = dict(os.environ, MPLBACKEND="Agg")
    env.pop("MILLPOST_UPDATE_SCREENSHOT", None)
    return env


def _run(argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(argv, cwd=cwd, env=_env(), capture_output=True, text=True, timeout=TIMEOUT_S,
                          stdin=subprocess.DEVNULL)


def _folder(tmp_path: Path) -> Path:
    shutil.copytree(ROOT / "sample_jobs", tmp_path / "sample_jobs",
                    ignore=shutil.ignore_patterns("*.millpost.nc", "__pycache__"))
    return tmp_path


def _check_shown_output(block: Block, command: str, shown: list[str], printed: str) -> None:
    """Each shown line's words up to its first number start a line of what the command printed."""
    got = printed.splitlines()
    for line in shown:
        prefix = re.split(r"\d", line, maxsplit=1)[0]
        if prefix.strip():
            assert any(g.startswith(prefix) for g in got), (
                f"{block.where}: `{command}` printed no line starting {prefix!r}; it printed:\n{printed}")


def _run_command(block: Block, command: str, shown: list[str], cwd: Path, expect: int) -> None:
    words = shlex.split(command)
    assert words[0] == "millpost", f"{block.where}: {command}"
    r = _run(_millpost() + words[1:], cwd)
    printed = r.stdout + r.stderr
    assert r.returncode == expect, f"{block.where}: `{command}` exited {r.returncode}, not {expect}:\n{printed}"
    _check_shown_output(block, command, shown, printed)


def _shell_blocks() -> list[Block]:
    return [b for p in PAGES for b in blocks(p) if b.lang in ("sh", "bash", "shell", "console")]


def _pages_with_commands() -> list[Path]:
    return [p for p in PAGES if any(b.is_millpost() or "run" in b.markers for b in blocks(p))]


# --- the tests ------------------------------------------------------------------------------------------
def test_the_site_builds_strict(tmp_path):
    """mkdocs build --strict: a broken link or anchor, a page outside the nav, a nav entry without its page
    fail the build; the site fetches nothing (no CDN script or style)."""
    try:
        import mkdocs  # noqa: F401
    except ImportError:
        pytest.fail("mkdocs is not installed: pip install -e '.[test]'")
    site = tmp_path / "site"
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(ROOT / "mkdocs.yml"),
                        "-d", str(site)], cwd=ROOT, capture_output=True, text=True, timeout=TIMEOUT_S)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "WARNING" not in r.stderr, r.stderr
    for page in DOCS.glob("*.md"):
        assert (site / page.with_suffix(".html").name).is_file(), page
    for html in site.glob("*.html"):
        text = html.read_text()
        assert not re.search(r"""<(script|link)[^>]+(src|href)="https?://""", text), f"{html.name} fetches from the network"


def test_readme_is_short_and_keeps_the_two_set_up_commands():
    """Under 200 lines; every file it links to exists (mkdocs checks the docs' links, not the README's); its
    test command is .ci/run's, verbatim (CI's contract), and its first command optimizes the bundled sample."""
    text = README.read_text()
    assert len(text.splitlines()) < 200
    ci = [l for l in (ROOT / ".ci" / "run").read_text().splitlines() if l.startswith("python3 -m venv")]
    assert len(ci) == 1, ci
    for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
        assert target.startswith("http") or (ROOT / target).exists(), f"README links to {target}, which is absent"
    assert _set_up_commands() == ["python3 -m venv .venv && .venv/bin/pip install -q -e . && .venv/bin/millpost optimize "
                     "sample_jobs/adaptive_pocket --json -", ci[0]]


def _set_up_commands() -> list[str]:
    return [b.text.strip() for b in blocks(README) if b.text.startswith("python3 -m venv")]


def test_every_shell_block_is_a_command_that_runs_or_is_marked():
    """No shell block escapes the command test: each starts with millpost (run, or marked not run with a
    reason), and a set-up command shown anywhere is one of the README's two."""
    for b in (b for p in PAGES for b in blocks(p)):
        if b.text.startswith("python3 -m venv"):
            assert b.text.strip() in _set_up_commands(), f"{b.where}: not one of the README's set-up commands"
        elif b.lang in ("sh", "bash", "shell", "console"):
            assert b.is_millpost(), (f"{b.where}: a shell block that the command test cannot run; show "
                                     f"`millpost ...` commands or mark it <!-- not run: reason -->")
        if "not run" in b.markers:
            assert b.markers["not run"], f"{b.where}: `not run` needs its reason"


def test_the_readme_set_up_command_runs(tmp_path):
    """The first set-up command's millpost part (the install is the test run's own)."""
    cwd = _folder(tmp_path)
    block = next(b for b in blocks(README) if b.text.startswith("python3 -m venv .venv && .venv/bin/pip install -q -e . "))
    command = block.text.strip().split(" && ")[-1]
    assert command.startswith(".venv/bin/millpost ")
    _run_command(block, command.removeprefix(".venv/bin/"), [], cwd, 0)
    assert (cwd / "sample_jobs" / "adaptive_pocket" / "program.millpost.nc").is_file()


@pytest.mark.parametrize("block", [b for p in PAGES for b in blocks(p) if "not run" in b.markers],
                         ids=lambda b: b.where)
def test_marked_not_run(block):
    """Listed for the record: a command the test cannot run here (it needs hardware)."""
    pytest.skip(f"{block.where}: {block.markers['not run']}: {block.commands()[0][0]}")


@pytest.mark.parametrize("page", _pages_with_commands(), ids=lambda p: str(p.relative_to(ROOT)))
def test_the_commands_of_a_page_run(page, tmp_path):
    """The page's commands, Python blocks and files in order, in a folder of its own with sample_jobs/."""
    cwd = _folder(tmp_path)
    ran = 0
    for b in blocks(page):
        if "not run" in b.markers:
            continue
        if "test setup" in b.markers:
            SETUPS[b.markers["test setup"]](cwd)
        if "file" in b.markers:
            (cwd / b.markers["file"]).write_text(b.text)
        elif b.markers.get("run") == "python":
            assert b.lang == "python", b.where
            r = _run([sys.executable, "-c", b.text], cwd)
            assert r.returncode == 0, f"{b.where}: the Python block failed:\n{r.stdout}{r.stderr}"
            ran += 1
        elif b.is_millpost():
            expect = int(b.markers.get("exit", 0))
            for command, shown in b.commands():
                _run_command(b, command, shown, cwd, expect)
                ran += 1
    assert ran
