"""Table 2 of a campaign as text: the Markdown table and document (table2.md), the
per-instance CSV (table2.csv) and the counts both are made of. The rows come from
:func:`parley_core.experiment.report.analyze`."""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from parley_core.experiment.store import RunRecord

Row = Any
"""A :class:`parley_core.experiment.report.Row` (not imported: that module imports this one)."""
Setting = tuple[float, ...]


def counts(rows: Sequence[Row], setting: Setting, attribute: str) -> tuple[int, int, int]:
    verdicts = [getattr(r, attribute) for r in rows if r.setting == setting]
    return verdicts.count("better"), verdicts.count("worse"), verdicts.count("same")


VERDICTS = (("hv", "HV"), ("spread", "SP"), ("gap", "paper's SP"), ("igd", "IGD+"))
"""Table 2's comparisons with the baseline: the verdict attribute's prefix and its column."""


def bound_gaps(rows: Sequence[Row], setting: Setting | None = None) -> list[float]:
    """Every repetition's gap to its instance's certified bound, (bound - front) / bound of
    the hypervolumes in the setting's box, over the rows of ``setting`` (None: all)."""
    from parley_core.experiment.bounds import gaps

    return [g for r in rows if setting is None or r.setting == setting for g in gaps(r.bound_hv, r.hv)]


def median_gap_text(rows: Sequence[Row], setting: Setting | None = None) -> str:
    found = bound_gaps(rows, setting)
    return f"{100 * float(np.median(found)):.1f} % (max {100 * max(found):.1f} %)" if found else "n/a"


def has_bounds(rows: Sequence[Row]) -> bool:
    return bool(bound_gaps(rows))


ANSWERS = ("feasible", "infeasible", "unknown")


def has_answers(rows: Sequence[Row]) -> bool:
    return any(r.answer for r in rows)


def answer_text(rows: Sequence[Row], setting: Setting | None = None) -> str:
    """How many cells (of ``setting``; None: all) are feasible / infeasible / unknown, and how
    many no check has answered yet."""
    chosen = [r.answer for r in rows if setting is None or r.setting == setting]
    text = "/".join(str(chosen.count(a)) for a in ANSWERS)
    missing = chosen.count("")
    return text + (f" ({missing} not checked)" if missing else "")


def table2_cells(
    rows: Sequence[Row], settings: Sequence[Setting], names: Sequence[str], published: bool
) -> tuple[list[str], list[list[str]]]:
    """Table 2 as cells: the header, then one line per setting and the total line (its
    setting cells empty but the first, "all"). table2.md and report.html draw these."""
    bounded = has_bounds(rows)
    head = [*names, *(f"{label} better/worse/same" for _, label in VERDICTS)]
    if published:
        head += ["HV vs published better/worse/same", "median HV >= published"]
    if bounded:
        head.append("median gap to the bound")
    answered = has_answers(rows)
    if answered:
        head.append("policy in the box: feasible/infeasible/unknown")
    groups = len(VERDICTS) + (1 if published else 0)
    totals = np.zeros((groups, 3), dtype=int)
    lines = []
    for setting in settings:
        found = [counts(rows, setting, f"{key}_verdict") for key, _ in VERDICTS]
        if published:
            found.append(counts(rows, setting, "published_verdict"))
        totals += np.array(found, dtype=int)
        line = [f"{b:g}" for b in setting] + ["/".join(map(str, c)) for c in found]
        if published:
            selected = [r for r in rows if r.setting == setting and r.published_hv]
            at_least = sum(np.median(r.hv) >= np.median(r.published_hv) for r in selected)
            line.append(f"{at_least}/{len(selected)}")
        if bounded:
            line.append(median_gap_text(rows, setting))
        if answered:
            line.append(answer_text(rows, setting))
        lines.append(line)
    total = ["all"] + [""] * (len(names) - 1) + ["/".join(map(str, t)) for t in totals]
    if published:
        total.append("")
    if bounded:
        total.append(median_gap_text(rows))
    if answered:
        total.append(answer_text(rows))
    lines.append(total)
    return head, lines


def table2_markdown(rows: Sequence[Row], settings: Sequence[Setting], names: Sequence[str], published: bool) -> str:
    head, lines = table2_cells(rows, settings, names, published)

    def markdown(cells: Sequence[str]) -> str:
        return "|" + "".join(f" {c} |" if c else " |" for c in cells) + "\n"

    return markdown(head) + "|" + "---|" * len(head) + "\n" + "".join(markdown(line) for line in lines)


def table2_document(
    campaign: str,
    case_name: str,
    settings_record,
    records: Sequence[RunRecord],
    rows: Sequence[Row],
    settings: Sequence[Setting],
    header: Sequence[str],
    published: bool,
) -> str:
    """table2.md: what the campaign holds, whose values its fronts are, and Table 2."""
    instances = {r.instance for r in records}
    reps = {r.repetition for r in records}
    checked = [r for r in records if r.verified]
    worst = max((r.verification.max_difference for r in checked if r.verification), default=0.0)
    if len(checked) == len(records):
        provenance = f"Storm's, every front re-checked (largest difference from the search's values {worst:.1e})"
    elif checked:
        provenance = (
            f"Storm's for {len(checked)} of {len(records)} runs (largest difference {worst:.1e}); the others the "
            "search evaluator's (`parley experiment verify` re-checks them)"
        )
    else:
        provenance = "the search evaluator's, not re-checked by Storm yet (`parley experiment verify` re-checks them)"
    return (
        f"# Campaign {campaign} ({case_name})\n\n{len(instances)} instances x {len(reps)} repetitions "
        f"({len(records)} runs); settings: {settings_record}.\nFront values: {provenance}.\n\n"
        "Per requirement setting (bounds), the number of instances where parley is significantly better / worse / "
        "not different from the baseline (Mann-Whitney U at 0.05 on the repetitions' gains against zero; A12 per "
        "instance in table2.csv). HV: hypervolume with the bounds as reference; SP: Deb's spread; paper's SP: the "
        "paper's mean neighbor distance; IGD+: distance from the best known front (lower is better for the last "
        "three)."
        + (
            " Median gap to the bound: over every run, (bound - front) / bound of the hypervolumes in the setting's "
            "box, where the bound is the instance's certified outer bound (`parley experiment bound`): no policy of "
            "the family is beyond it, so a front's hypervolume cannot exceed the bound's."
            if has_bounds(rows)
            else ""
        )
        + (
            " Policy in the box: per setting, the instances where a policy of the family meets both bounds "
            "(feasible: a policy whose values, Storm's, are inside), where none can (infeasible: the certified bound "
            "or branch and bound proves it) and where neither is known (`parley experiment check`)."
            if has_answers(rows)
            else ""
        )
        + "\n\n"
        + table2_markdown(rows, settings, header, published)
    )


def rows_csv(rows: Sequence[Row], names: Sequence[str]) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(
        [
            "instance",
            *(f"bound_{n}" for n in names),
            "baseline_hv",
            "median_hv",
            "hv_verdict",
            "hv_p",
            "hv_a12",
            "baseline_spread",
            "median_spread",
            "spread_verdict",
            "spread_p",
            "spread_a12",
            "baseline_paper_spread",
            "median_paper_spread",
            "paper_spread_verdict",
            "baseline_igd_plus",
            "median_igd_plus",
            "igd_plus_verdict",
            "published_median_igd_plus",
            "published_median_hv",
            "published_verdict",
            "published_p",
            "published_a12",
            "bound_hv",
            "median_bound_gap",
            "answer",
        ]
    )
    for r in rows:
        writer.writerow(
            [
                r.instance,
                *r.setting,
                r.baseline_hv,
                float(np.median(r.hv)),
                r.hv_verdict,
                r.hv_p,
                r.hv_a12,
                r.baseline_spread,
                float(np.median(r.spread)),
                r.spread_verdict,
                r.spread_p,
                r.spread_a12,
                r.baseline_gap,
                float(np.median(r.gap)),
                r.gap_verdict,
                r.baseline_igd,
                float(np.median(r.igd)),
                r.igd_verdict,
                float(np.median(r.published_igd)) if r.published_igd else "",
                float(np.median(r.published_hv)) if r.published_hv else "",
                r.published_verdict,
                "" if not r.published_hv else r.published_p,
                "" if not r.published_hv else r.published_a12,
                r.bound_hv if np.isfinite(r.bound_hv) else "",
                float(np.median(bound_gaps([r]))) if bound_gaps([r]) else "",
                r.answer,
            ]
        )
    return out.getvalue()
