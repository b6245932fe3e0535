"""The README is the front door (issue 25): one screen of at most 200 lines, and every relative link in it (the
docs' Markdown pages, the picture) names a file of the repository."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
LINK = re.compile(r"\]\(([^)\s]+)\)")


def test_the_readme_is_at_most_200_lines():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 200, f"README.md has {len(lines)} lines; guides and reference belong in docs/"


def test_every_relative_link_of_the_readme_names_a_file():
    targets = [t for t in LINK.findall(README.read_text(encoding="utf-8")) if "://" not in t and not t.startswith("#")]
    assert targets, "the README links into the docs"
    missing = [t for t in targets if not (ROOT / t.split("#", 1)[0]).is_file()]
    assert not missing, f"README links to files that do not exist: {missing}"


def test_the_readme_points_into_each_part_of_the_docs():
    text = README.read_text(encoding="utf-8")
    for page in ("docs/getting-started.md", "docs/model.md", "docs/reference/cli.md", "docs/benchmarks.md"):
        assert f"({page})" in text, page
