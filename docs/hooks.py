"""MkDocs hook: the site's home page is the README, its links to docs/ pages made relative to the site."""

from pathlib import Path

README = Path(__file__).resolve().parent.parent / "README.md"


def on_page_markdown(markdown: str, page, **kwargs) -> str:
    """The README's text in place of docs/index.md's, with ``docs/`` dropped from its links and image paths."""
    if page.file.src_uri != "index.md":
        return markdown
    return README.read_text().replace("](docs/", "](").replace('src="docs/', 'src="')
