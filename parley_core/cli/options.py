"""The command-line option types shared by several commands; search defaults come from
:class:`~parley_core.search.SearchSettings`."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from parley_core.search import ALGORITHMS, default

SetOption = Annotated[
    list[str] | None,
    typer.Option(
        "--set", "-s", metavar="KEY=VALUE", help="A case-study option (repeatable); see `parley options CASE`."
    ),
]
WorkersOption = Annotated[
    int | None, typer.Option("--workers", "-j", min=1, help="Worker processes for Storm (default: one per core).")
]
EvaluatorOption = Annotated[
    str,
    typer.Option(
        "--evaluator",
        help="quotient: one MDP for all policies, fast; storm: build and check each policy (the reference).",
    ),
]
ConstraintOption = Annotated[
    list[str] | None,
    typer.Option(
        "--constraint",
        metavar="NAME>=BOUND",
        help="A requirement the policies must meet, e.g. success>=0.8 (repeatable).",
    ),
]
DecisionOption = Annotated[
    list[str],
    typer.Option(
        "--decision",
        metavar="NAME=LOW..HIGH[:KIND]",
        help="A constant that sets when a service runs, and its values (repeatable).",
    ),
]
ObserveOption = Annotated[
    list[str] | None,
    typer.Option(
        "--observe",
        metavar="VAR,...",
        help="Variables the URC may read (none: one value per decision constant, as PAYNT's holes).",
    ),
]
JsonOption = Annotated[bool, typer.Option("--json", help="Print one JSON document to stdout and nothing else there.")]
ForceOption = Annotated[bool, typer.Option(help="Replace the files of an existing --out directory.")]
CaseArgument = Annotated[
    str,
    typer.Argument(
        metavar="CASE",
        help="Case study: robot_grid, turtlebot, web_ids, tas, or an installed plugin's (`parley list` lists them).",
        show_default=False,
    ),
]

ALGORITHM = default("algorithm")
AlgorithmOption = Annotated[
    str,
    typer.Option(
        "--algorithm",
        help=f"Search configuration: {', '.join(ALGORITHMS)} (docs/search.md says what each is).",
    ),
]
SEED = default("seed")
POPULATION = default("population")
SeedOption = Annotated[int, typer.Option(help="Seed of the search; the same seed gives the same front.")]
PopulationOption = Annotated[int, typer.Option(min=2, help="NSGA-II population size.")]
GenerationsOption = Annotated[
    int | None,
    typer.Option(
        min=1,
        show_default=False,
        help=f"NSGA-II generations (default: {default('generations')}, "
        "or no limit when --max-evaluations or --time-limit is given).",
    ),
]
MaxEvaluationsOption = Annotated[
    int | None,
    typer.Option("--max-evaluations", min=1, help="Stop after this many policies (the baselines included)."),
]
TimeLimitOption = Annotated[
    float | None, typer.Option("--time-limit", min=0.001, help="Stop the search after this many seconds.")
]
BoundOption = Annotated[
    str,
    typer.Option(
        "--bound",
        help="pareto (default): a certified outer bound of the family and the front's gap to it (the quotient's "
        "relaxation's Pareto curve approximated from outside by weighted sums; two objectives, else the ideal "
        "point); ideal: the best per objective over all schedulers of the relaxation; belief: pareto on an ideal "
        "point tightened by Storm's belief exploration of the relaxation read as a POMDP (unbounded reachability "
        "objectives only); refine: branch and bound over the decisions' ranges "
        "after the search, for --bound-time seconds (a tighter bound, its policies join the front; exact when "
        "it finishes); none: skip it.",
    ),
]
BOUND_SECONDS = 60.0
"""--bound-time when it is not given (and no --exact asks for no limit)."""
BoundTimeOption = Annotated[
    float | None,
    typer.Option(
        "--bound-time",
        min=0.001,
        help="With --bound refine: stop branch and bound after this many seconds (default 60; with --exact, no "
        "limit). With --bound belief: stop Storm's belief exploration after this many seconds per objective (default "
        "60; its MDP value stands then).",
    ),
]
ExactOption = Annotated[
    bool,
    typer.Option(
        "--exact",
        help="Branch and bound until the front is proven the family's whole Pareto front (--bound refine without a "
        "time limit, unless --bound-time gives one; Ctrl-C stops it with the front and bound so far).",
    ),
]
VerifyWithOption = Annotated[
    str,
    typer.Option(
        "--verify-with",
        help="batch (default): Storm checks policy programs, the original model with the decisions as a formula, "
        "several policies per build; reference: Storm checks the augmented model, one policy per build (slower; "
        "the path the tests compare with).",
    ),
]
ScenariosOption = Annotated[
    list[str] | None,
    typer.Option(
        "--scenarios",
        metavar="KEY=V1,V2,...|FILE.csv",
        help="A robust run: score each policy by its worst value over these scenarios (values of a case-study "
        "option, or of a model constant for `synthesize`; repeat for a grid of several, or give a CSV file with "
        "a header of names and a scenario per row). Every front policy is checked by Storm in every scenario; "
        "scenarios.csv holds each one's values.",
    ),
]
WarmStartOption = Annotated[
    Path | None,
    typer.Option(
        "--warm-start",
        metavar="RUN_DIR",
        help="Start the search from the front of an earlier run of the same family (its policies.csv), say for "
        "other numbers of the model, besides the baselines.",
    ),
]
OutOption = Annotated[Path | None, typer.Option(help="Run directory (default: runs/NAME-TIMESTAMP).")]
