"""MkDocs hook: the docstrings' Sphinx roles (:func:`x`, :class:`x`, ...) render as plain code in the API pages."""

import re

ROLE = re.compile(r":(?:attr|class|data|exc|func|meth|mod|obj):(?=<code)")


def on_page_content(html: str, **kwargs: object) -> str:
    return ROLE.sub("", html)
