"""Campaign reports: the paper's Table 2 and Fig. 4, and the comparison with published fronts.

For each requirement setting (one bound per objective: the worst acceptable value, e.g.
success >= 0.7 and cost <= 80), each run's front and the instance's baseline are cut to the
points that meet every bound, and measured against the bounds:

- hypervolume with the bounds as reference point (:func:`parley_core.metrics.hypervolume`);
- Deb's spread, normalized by the setting's box and with the extremes of all fronts of
  that instance (every repetition and the baseline) as the reference extremes;
- the paper's "spread" (:func:`parley_core.metrics.mean_gap`), for comparison with its Table 2;
- IGD+ against the non-dominated union of all fronts of the instance inside the box
  (normalized like the spread): how far a front stays from the best known trade-offs.

Per instance and setting, the repetitions' gains over the baseline are tested against zero
with a two-sided Mann-Whitney U at 0.05 (as the paper does, but pairing every repetition
with its own instance's baseline) and their Vargha-Delaney A12 is reported. With published
fronts, the repetitions' hypervolumes are compared with the published repetitions' the same
way. See docs/metrics.md.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from attrs import frozen

from parley_core import metrics
from parley_core.errors import OptionError
from parley_core.experiment import bounds as instance_bounds
from parley_core.experiment.stats import compare
from parley_core.experiment.store import RunRecord
from parley_core.experiment.table2 import rows_csv, table2_cells, table2_document
from parley_core.model import Direction
from parley_core.plugin.casestudy import CaseStudy
from parley_core.views.plotting import figure, save

Setting = tuple[float, ...]


@frozen(kw_only=True)
class Row:
    instance: str
    setting: Setting
    baseline_hv: float
    hv: tuple[float, ...]
    hv_verdict: str
    hv_p: float
    hv_a12: float
    baseline_spread: float
    spread: tuple[float, ...]
    spread_verdict: str
    spread_p: float
    spread_a12: float
    baseline_gap: float = float("nan")
    gap: tuple[float, ...] = ()
    gap_verdict: str = ""
    baseline_igd: float = float("nan")
    igd: tuple[float, ...] = ()
    igd_verdict: str = ""
    published_igd: tuple[float, ...] = ()
    published_hv: tuple[float, ...] = ()
    published_verdict: str = ""
    published_p: float = float("nan")
    published_a12: float = float("nan")
    bound_hv: float = float("nan")
    """The hypervolume of the instance's certified bound in the setting's box (nan: none stored)."""
    answer: str = ""
    """Whether a policy of the instance's family meets the setting: "feasible", "infeasible",
    "unknown", or "" if ``parley experiment check`` has not answered the cell."""


def parse_setting(text: str, n_objectives: int) -> Setting:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise OptionError(f"malformed --setting {text!r}; give one bound per objective, e.g. 0.7,80") from None
    if len(values) != n_objectives:
        raise OptionError(f"--setting {text!r} has {len(values)} bounds; give one per objective ({n_objectives})")
    return values


def in_box(values: np.ndarray, directions: Sequence[Direction], setting: Setting) -> np.ndarray:
    signs = np.array([d.sign for d in directions])
    return values[((values * signs) < (np.array(setting) * signs)).all(axis=1)] if len(values) else values


def _spread(values: np.ndarray, directions, setting: Setting, ideal: np.ndarray, extremes: np.ndarray | None) -> float:
    points = metrics.distinct_front(in_box(values, directions, setting), directions)
    return metrics.spread(points, directions, bounds=(ideal, np.array(setting)), extremes=extremes)


def _gap(values: np.ndarray, directions, setting: Setting) -> float:
    return metrics.mean_gap(metrics.distinct_front(in_box(values, directions, setting), directions), directions)


def _igd(values: np.ndarray, directions, setting: Setting, ideal: np.ndarray, reference: np.ndarray) -> float:
    if len(reference) == 0:
        return float("nan")
    return metrics.igd_plus(
        in_box(values, directions, setting), reference, directions, bounds=(ideal, np.array(setting))
    )


def published_fronts(directory: Path, instance: str, n_objectives: int) -> list[np.ndarray]:
    """Published fronts of an instance: ``{instance}_rep{R}.front.tsv`` (a header line, then one tab-separated
    row per policy)."""
    fronts = []
    for path in sorted(
        directory.glob(f"{instance}_rep*.front.tsv"), key=lambda p: int(p.stem.split("_rep")[-1].split(".")[0])
    ):
        rows = [line.split("\t")[:n_objectives] for line in path.read_text().splitlines()[1:] if line.strip()]
        fronts.append(np.array(rows, dtype=float).reshape(-1, n_objectives))
    return fronts


def analyze(
    records: Sequence[RunRecord],
    settings: Sequence[Setting],
    published: Path | None = None,
    bounds: Mapping[str, np.ndarray] | None = None,
    answers: Mapping[tuple[str, Setting], Mapping[str, Any]] | None = None,
) -> list[Row]:
    by_instance: dict[str, list[RunRecord]] = defaultdict(list)
    for record in records:
        by_instance[record.instance].append(record)
    rows = []
    for instance, runs in by_instance.items():
        runs = sorted(runs, key=lambda r: r.repetition)
        directions = [o.direction for o in runs[0].objectives]
        fronts = [r.values()[0] for r in runs]
        baseline = runs[0].values()[1]
        theirs = published_fronts(published, instance, len(directions)) if published else []
        everything = np.vstack([baseline, *fronts, *theirs])
        as_min = everything * np.array([d.sign for d in directions])
        ideal = as_min.min(axis=0) * np.array([d.sign for d in directions])
        for setting in settings:
            box_all = in_box(everything, directions, setting)
            box_front = metrics.distinct_front(box_all, directions)
            extremes = None
            if len(box_front) >= 2:
                order = np.argsort(box_front[:, 0] * directions[0].sign)
                extremes = box_front[[order[0], order[-1]]]
            base_hv = metrics.hypervolume(baseline, directions, setting)
            hv = tuple(metrics.hypervolume(f, directions, setting) for f in fronts)
            base_sp = _spread(baseline, directions, setting, ideal, extremes)
            sp = tuple(_spread(f, directions, setting, ideal, extremes) for f in fronts)
            hv_test = compare([h - base_hv for h in hv], [0.0] * len(hv))
            # spread: lower is better, so "better" means the gains are below zero
            sp_test = compare([0.0] * len(sp), [s - base_sp for s in sp])
            base_gap = _gap(baseline, directions, setting)
            gap = tuple(_gap(f, directions, setting) for f in fronts)
            gap_test = compare([0.0] * len(gap), [g - base_gap for g in gap])
            base_igd = _igd(baseline, directions, setting, ideal, box_front)
            igd = tuple(_igd(f, directions, setting, ideal, box_front) for f in fronts)
            igd_test = compare([0.0] * len(igd), [i - base_igd for i in igd]) if len(box_front) else None
            row: dict[str, Any] = dict(
                instance=instance,
                setting=tuple(setting),
                baseline_hv=base_hv,
                hv=hv,
                hv_verdict=hv_test.verdict,
                hv_p=hv_test.p_value,
                hv_a12=hv_test.a12,
                baseline_spread=base_sp,
                spread=sp,
                spread_verdict=sp_test.verdict,
                spread_p=sp_test.p_value,
                spread_a12=sp_test.a12,
                baseline_gap=base_gap,
                gap=gap,
                gap_verdict=gap_test.verdict,
                baseline_igd=base_igd,
                igd=igd,
                igd_verdict=igd_test.verdict if igd_test else "same",
                bound_hv=instance_bounds.hypervolume((bounds or {}).get(instance), directions, setting),
                answer=str((answers or {}).get((instance, tuple(setting)), {}).get("answer", "")),
            )
            if theirs:
                their_hv = tuple(metrics.hypervolume(f, directions, setting) for f in theirs)
                test = compare(hv, their_hv)
                row.update(
                    published_hv=their_hv,
                    published_verdict=test.verdict,
                    published_p=test.p_value,
                    published_a12=test.a12,
                )
                row.update(published_igd=tuple(_igd(f, directions, setting, ideal, box_front) for f in theirs))
            rows.append(Row(**row))
    return rows


def box_plots(rows: Sequence[Row], setting: Setting, caption: str, path_stem: Path) -> list[Path]:
    """Fig. 4: per instance, the repetitions' hypervolume gains and spread gains over the baseline."""
    selected = [r for r in rows if r.setting == setting]
    written = []
    for key, label in (("hv", "hypervolume gain (higher is better)"), ("spread", "spread gain (lower is better)")):
        base = "baseline_hv" if key == "hv" else "baseline_spread"
        data = [np.array(getattr(r, key)) - getattr(r, base) for r in selected]
        width = max(6.0, 0.14 * len(selected) + 2)
        fig, ax = figure(width, 3.8)
        ax.boxplot(data, showfliers=True, flierprops={"markersize": 2})
        ax.axhline(0.0, color="tab:red", lw=0.8)
        ax.set_xticks(range(1, len(selected) + 1))
        ax.set_xticklabels([r.instance.replace("map_", "") for r in selected], rotation=90, fontsize=6)
        ax.set_ylabel(label)
        ax.set_title(f"{label.split(' (')[0]} per instance, {caption}", fontsize=10)
        fig.tight_layout()
        for suffix in (".png", ".pdf"):
            target = path_stem.with_name(f"{path_stem.name}_{key}{suffix}")
            save(fig, target, dpi=140, tight=False)
            written.append(target)
    return written


def write_report(
    records: Sequence[RunRecord],
    out: Path,
    *,
    campaign: str,
    case: CaseStudy,
    settings_record: dict,
    settings: Sequence[Setting] | None = None,
    figure_setting: Setting | None = None,
    published: Path | None = None,
    bounds: Mapping[str, np.ndarray] | None = None,
    answers: Mapping[tuple[str, Setting], Mapping[str, Any]] | None = None,
) -> tuple[str, list[Path]]:
    """Write table2.md, table2.csv and the box plots of a campaign into ``out``; returns
    table2.md's text and the files written. ``settings`` default to the case study's
    requirement settings; the box plots show ``figure_setting``, by default the case
    study's own if it is among the settings, else the first setting."""
    if not records:
        raise OptionError(f"campaign {campaign} has no finished run yet")
    objectives = records[0].objectives
    names = [o.name for o in objectives]
    settings = list(settings) if settings else list(case.requirement_settings)
    if not settings:
        raise OptionError(f"{case.name} declares no requirement settings; give --setting (one bound per objective)")
    if figure_setting is None:
        figure_setting = case.figure_setting if case.figure_setting in settings else settings[0]
    rows = analyze(records, settings, published, bounds, answers)
    header = [f"{o.name} {'>=' if o.direction is Direction.MAX else '<='}" for o in objectives]
    text = table2_document(campaign, case.name, settings_record, records, rows, settings, header, published is not None)
    out.mkdir(parents=True, exist_ok=True)
    (out / "table2.md").write_text(text)
    (out / "table2.csv").write_text(rows_csv(rows, names))
    caption = ", ".join(f"{h} {b:g}" for h, b in zip(header, figure_setting))
    figures = box_plots(rows, figure_setting, caption, out / "gains")
    from parley_core.experiment import page as campaign_page

    page = campaign_page.render(
        rows,
        settings,
        header,
        table=table2_cells(rows, settings, header, published is not None),
        title=f"parley campaign {campaign} ({case.name})",
        description=text.split("\n\n")[1] if "\n\n" in text else "",
        chosen=figure_setting,
    )
    (out / campaign_page.REPORT).write_text(page, encoding="utf-8")
    return text, [out / "table2.md", out / "table2.csv", *figures, out / campaign_page.REPORT]
