"""The library API, published as the :mod:`parley` package: one function per command that
makes results, value objects out. See :mod:`parley` for the tour."""

from parley_core.api.campaigns import (
    Campaign,
    CampaignReport,
    campaign_bounds,
    campaign_check,
    campaign_report,
    experiment,
)
from parley_core.api.commands import check, check_model, exact, recheck, run, synthesize
from parley_core.api.evaluation import augment, baseline, case_studies, evaluate
from parley_core.api.runs import Check, Optimality, Run, Selection, Summary, load, load_check

__all__ = [
    "Campaign",
    "CampaignReport",
    "Check",
    "Optimality",
    "Run",
    "Selection",
    "Summary",
    "augment",
    "baseline",
    "campaign_bounds",
    "campaign_check",
    "campaign_report",
    "case_studies",
    "check",
    "check_model",
    "evaluate",
    "exact",
    "experiment",
    "load",
    "load_check",
    "recheck",
    "run",
    "synthesize",
]
