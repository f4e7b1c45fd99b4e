"""MkDocs hook: heading ids that are valid CSS selectors.

Numbered headings ("## 1. Roll-up by an end moment") would get ids starting
with a digit ("1-roll-up-by-an-end-moment"), which are not valid CSS
selectors and break the theme's scroll spy.  The slug drops the leading
section number ("roll-up-by-an-end-moment") and, if it still starts with a
digit, gets the prefix ``s-``.
"""
import re

from pymdownx.slugs import slugify as _slugify

_base = _slugify(case="lower")


def slugify(text, sep):
    slug = _base(re.sub(r"^\s*\d+(\.\d+)*\.?\s+", "", text), sep)
    return f"s{sep}{slug}" if slug[:1].isdigit() else slug


def on_config(config):
    config.mdx_configs.setdefault("toc", {})["slugify"] = slugify
    return config
