"""Deterministic pages: Bokeh names its models by a process-wide counter (``p1141``) and its
documents and elements by random UUIDs, so the same run would give a different
``report.html`` each time. :func:`stable_ids` renumbers both in order of first appearance
within the document part of the page (after Bokeh's inline library code, which it leaves
alone), so equal runs give byte-equal pages."""

from __future__ import annotations

import re

_UUID = re.compile(r"[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}")
# where Bokeh writes a model id: its definition and references ("id":"p1141"), the root
# element (data-root-id="p1141") and the render items ("roots":{"p1141": ..., "root_ids":["p1141"]);
# never elsewhere, so data that looks like an id (a policy named p1022) stays as it is
_MODEL = re.compile(
    r'(?<="id":")p\d+(?=")|(?<=data-root-id=")p\d+(?=")|(?<="roots":\{")p\d+(?=")|(?<="root_ids":\[")p\d+(?=")'
)
_ROOT = re.compile(r'<div id="[^"]+" data-root-id=')


def stable_ids(page: str) -> str:
    start = _ROOT.search(page)
    if start is None:
        return page
    head, tail = page[: start.start()], page[start.start() :]
    uuids: dict[str, str] = {}
    models: dict[str, str] = {}

    def uuid(match: re.Match[str]) -> str:
        return uuids.setdefault(match.group(0), f"00000000-0000-4000-8000-{len(uuids) + 1:012d}")

    def model(match: re.Match[str]) -> str:
        return models.setdefault(match.group(0), f"p{len(models) + 1001}")

    return head + _MODEL.sub(model, _UUID.sub(uuid, tail))
