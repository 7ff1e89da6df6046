"""The documentation's shape (issue 31): README.md is the front page (about 400 lines: what dampnet
is, the quick start, one door per reader, links) and the reference is docs/, one Markdown file per
topic. Every relative link in README.md and docs/*.md reaches an existing file, and its anchor, if
it has one, a heading of that file (GitHub's heading ids); every docs/ file is linked from README;
CI's test command is the README's."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
README_MAX_LINES = 250  # issue 52: the quick start and the doors; the rest is in docs/
FENCE = re.compile(r"^```.*?^```[^\n]*$", re.MULTILINE | re.DOTALL)
LINK = re.compile(r"\[((?:[^\[\]]|\[[^\]]*\])*)\]\(([^()\s]+)(?:\s+\"[^\"]*\")?\)")


def prose(text: str) -> str:
    """The text without fenced code blocks and inline code spans (links there are not links)."""
    text = FENCE.sub("", text)
    return re.sub(r"`[^`\n]*`", "``", text)


def heading_ids(path: Path) -> set[str]:
    """The anchors GitHub gives the file's headings: lower case, punctuation but '-' and '_'
    dropped, spaces to '-', and '-1', '-2', ... on repeats."""
    ids: set[str] = set()
    seen: dict[str, int] = {}
    for line in FENCE.sub("", path.read_text()).splitlines():
        m = re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
        if not m:
            continue
        title = LINK.sub(lambda k: k.group(1), m.group(1))
        slug = re.sub(r"[^\w\- ]", "", title.lower()).replace(" ", "-")
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        ids.add(slug if n == 0 else f"{slug}-{n}")
    return ids


def broken_links(path: Path) -> list[str]:
    """Every relative link of the Markdown file `path` whose file or anchor does not exist."""
    bad = []
    for label, target in LINK.findall(prose(path.read_text())):
        if re.match(r"^[a-zA-Z][a-zA-Z0-9+.-]*:", target):        # http:, https:, mailto:
            continue
        file_part, _, anchor = target.partition("#")
        dest = (path.parent / file_part).resolve() if file_part else path
        if not dest.exists():
            bad.append(f"{path.name}: [{label}]({target}): no file {dest}")
        elif anchor and dest.suffix == ".md" and anchor not in heading_ids(dest):
            bad.append(f"{path.name}: [{label}]({target}): no heading #{anchor} in {dest.name}")
    return bad


def doc_files() -> list[Path]:
    return [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))


@pytest.mark.parametrize("path", doc_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_reaches_a_file_and_its_heading(path):
    assert broken_links(path) == []


def test_the_link_check_sees_a_missing_file_and_a_missing_heading(tmp_path):
    (tmp_path / "other.md").write_text("# Other\n\n## The part: `x`, y\n\n## The part: `x`, y\n")
    doc = tmp_path / "doc.md"
    doc.write_text("# Doc\n\n[ok](other.md#the-part-x-y) [ok](other.md#the-part-x-y-1) [ok](#doc)\n"
                   "[gone](missing.md) [no heading](other.md#nothing) [self](#nowhere)\n"
                   "`[code](not-a-link.md)`\n\n```md\n[code](not-a-link.md)\n```\n"
                   "[web](https://example.org/x.md)\n")
    bad = broken_links(doc)
    assert len(bad) == 3, bad
    assert "missing.md" in bad[0] and "#nothing" in bad[1] and "#nowhere" in bad[2]


def test_readme_is_the_front_page_and_links_every_reference_file():
    readme = (ROOT / "README.md").read_text()
    n = len(readme.splitlines())
    assert n <= README_MAX_LINES, f"README.md has {n} lines; the reference belongs in docs/"
    linked = {Path(t.partition("#")[0]).name for _, t in LINK.findall(prose(readme)) if t.startswith("docs/")}
    docs = {p.name for p in (ROOT / "docs").glob("*.md")}
    assert docs - linked == set(), "docs/ files the README does not link"
    assert len(docs) >= 10                                   # the reference is split by topic


def test_the_quick_start_commands_are_the_ones_ci_runs():
    readme = (ROOT / "README.md").read_text()
    quick = readme[readme.index("## Quick start"):]
    block = quick[quick.index("```sh\n") + 6:]
    commands = [line.split("#")[0].strip() for line in block[:block.index("```")].splitlines()]
    assert commands == ["bash python/env.sh dampnet demo", "bash python/env.sh pytest"]
    ci = [line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()
          if line.strip() and not line.startswith(("#", "set ", "cd "))]
    assert ci == ["bash python/env.sh pytest"]


def documented_commands() -> list[tuple[str, str]]:
    """Every `dampnet ...` line of a shell block in README.md and docs/*.md, its comment dropped and
    an optional part's brackets removed (`[--mode pitch]`); lines with alternatives (`a|b`) or
    elisions (`...`) are templates, not command lines, and are left out."""
    found = []
    for path in doc_files():
        for block in re.findall(r"^```(?:sh|bash)\n(.*?)^```", path.read_text(), re.MULTILINE | re.DOTALL):
            for line in block.splitlines():
                cmd = re.sub(r"^bash python/env\.sh ", "", line.strip()).split(" #")[0].strip()
                cmd = re.sub(r"\[([^\[\]|]*)\]", r"\1", cmd)
                if cmd.startswith("dampnet ") and not any(s in cmd for s in ("|", "...", "[", "&&")):
                    found.append((path.name, cmd))
    return found


def test_every_documented_command_line_parses():
    """Each command line the README and docs/ print is one `dampnet` accepts: the command exists and
    takes those options (argparse only: nothing runs)."""
    import shlex

    from dampnet.cli import build_parser

    commands = documented_commands()
    assert len(commands) >= 30 and {c.split()[1] for _, c in commands} >= {
        "train", "evaluate", "diagnose", "simulate", "vehicle", "export", "plan-tests", "sweep", "bench"}
    refused = []
    for name, cmd in commands:
        try:
            build_parser().parse_args(shlex.split(cmd)[1:])
        except SystemExit as e:
            if e.code:
                refused.append(f"{name}: {cmd}")
    assert refused == []
