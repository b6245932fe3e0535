"""Check the internal links of the built docs: every relative ``href``/``src`` and every ``#anchor`` resolves.

    python tools/check_docs_links.py docs/_build/html

Parses every ``.html`` file under the folder, collects the ``id`` (and ``name``) attributes of each, and checks every
``href`` and ``src`` that points inside the site (no scheme, no ``//host``): the file it names exists under the
folder (a folder means its ``index.html``), and its ``#fragment``, if any, is an id of that page. ``mailto:``,
``http(s):`` and other schemes are not followed (the build is offline). Exits 1 listing the broken links, one per
line as ``page: link (why)``; 0 when all resolve. ``make docs`` runs it after Sphinx.
"""

from __future__ import annotations

import argparse
import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

#: Pages Sphinx writes that are not documentation (their links are the theme's and the search's own).
SKIPPED_PAGES = ("_static/", "_sources/", "_images/", "_downloads/")


class _Page(HTMLParser):
    """The ids of one page and its links (attribute value, line)."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.ids: set[str] = set()
        self.links: list[tuple[str, int]] = []

    def handle_starttag(self, tag, attrs):
        for name, value in attrs:
            if value is None:
                continue
            if name == "id" or (name == "name" and tag == "a"):
                self.ids.add(value)
            elif (name == "href" and tag in ("a", "link", "area")) or (
                    name == "src" and tag in ("img", "script", "iframe", "source", "video", "audio", "embed")):
                self.links.append((value, self.getpos()[0]))

    handle_startendtag = handle_starttag


def _internal(link: str) -> bool:
    parts = urlsplit(link)
    return not parts.scheme and not parts.netloc and not link.startswith("//")


def check(root: Path) -> list[str]:
    """The broken internal links under ``root``, as ``page:line: link (why)``."""
    root = root.resolve()
    pages = {}
    for path in sorted(root.rglob("*.html")):
        relative = path.relative_to(root).as_posix()
        if relative.startswith(SKIPPED_PAGES):
            continue
        parser = _Page()
        parser.feed(path.read_text(encoding="utf-8", errors="replace"))
        parser.close()
        pages[path] = parser
    ids_cache: dict[Path, set[str]] = {path: page.ids for path, page in pages.items()}

    def ids_of(path: Path) -> set[str]:
        if path not in ids_cache:
            parser = _Page()
            parser.feed(path.read_text(encoding="utf-8", errors="replace"))
            ids_cache[path] = parser.ids
        return ids_cache[path]

    broken = []
    for path, page in pages.items():
        where = path.relative_to(root).as_posix()
        for link, line in page.links:
            if not link or not _internal(link):
                continue
            parts = urlsplit(link)
            target = path if not parts.path else (path.parent / unquote(parts.path)).resolve()
            if target.is_dir():
                target = target / "index.html"
            if root not in target.parents and target != root:
                broken.append(f"{where}:{line}: {link} (outside the built site)")
                continue
            if not target.is_file():
                broken.append(f"{where}:{line}: {link} (no file {target.relative_to(root).as_posix()})")
                continue
            fragment = unquote(parts.fragment)
            if fragment and target.suffix == ".html" and fragment not in ids_of(target):
                broken.append(f"{where}:{line}: {link} (no id {fragment!r} in "
                              f"{target.relative_to(root).as_posix()})")
    return broken


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("site", type=Path, help="the built HTML folder (docs/_build/html)")
    args = parser.parse_args(argv)
    if not (args.site / "index.html").is_file():
        print(f"check_docs_links: {args.site} has no index.html (build the docs first: make docs)", file=sys.stderr)
        return 2
    broken = check(args.site)
    pages = sum(1 for p in args.site.rglob("*.html") if not p.relative_to(args.site).as_posix().startswith(
        SKIPPED_PAGES))
    if broken:
        print(f"check_docs_links: {len(broken)} broken internal link(s) in {args.site}:", file=sys.stderr)
        for line in broken:
            print(f"  {line}", file=sys.stderr)
        return 1
    print(f"check_docs_links: every internal link of {pages} pages resolves")
    return 0


if __name__ == "__main__":
    sys.exit(main())
