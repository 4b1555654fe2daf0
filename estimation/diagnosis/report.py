"""The report of a :class:`~estimation.diagnosis.search.Diagnosis` (:func:`diagnosis_report`: one document,
written as Markdown or HTML by :mod:`dynamics.runtime.report_document`) and its figures."""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from estimation.diagnosis.search import Diagnosis
from dynamics.channels import is_joint_torque, torque_joint
from dynamics.measurements import Measurements
from dynamics.runtime.output_files import save_figure
from dynamics.runtime.report_document import Block, Bullets, Figure as ReportFigure, Heading, Paragraph, Report, Table
from estimation.diagnosis.results import runner_up_line
from estimation.identification.report import parameter_table
from estimation.identification.validation import Comparison, plot_channel, subsample_step
from estimation.uncertainty.residual_tracing import ResidualTrace, TraceRow, plot_residual_trace, state_variables

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def plot_residuals(diagnosis: Diagnosis, train: Measurements, path: str | Path | None = None, *,
                   channels: Sequence[str] | None = None) -> Figure:
    """Training residuals of the declared model against q, dq, ddq of their joint, and time (of ``channels``,
    default all); saved to ``path`` when given."""
    from matplotlib.figure import Figure  # no pyplot; here, not at the top: a run without figures skips matplotlib

    estimate = diagnosis.before.estimate
    shown = list(estimate.channels if channels is None else channels)
    figure = Figure(figsize=(14, 2.2 * len(shown) + 0.6))
    axes = figure.subplots(len(shown), 4, squeeze=False)
    for row, channel in enumerate(shown):
        residual = estimate.residuals[:, list(estimate.channels).index(channel)]
        joint = torque_joint(channel) if is_joint_torque(channel) else 0
        for column, (label, values) in enumerate(
            (("q", train.q[:, joint]), ("dq", train.dq[:, joint]), ("ddq", train.ddq[:, joint]), ("t", train.t))
        ):
            axis = axes[row, column]
            axis.plot(values, residual, ".", markersize=1.5, alpha=0.4)
            axis.set_xlabel(f"{label}{joint + 1}" if label != "t" else "t [s]")
            if column == 0:
                axis.set_ylabel(f"residual {channel}")
    seen = ", the filtered or period-averaged channels the estimation saw" if train.recorded is not None else ""
    figure.suptitle(f"Residuals of the declared model (training data{seen})")
    figure.tight_layout()
    if path is not None:
        save_figure(figure, path, dpi=90)
    return figure


def markdown_report(diagnosis: Diagnosis, figure: str | None = None, trace_figure: str | None = None) -> str:
    """The diagnosis alone as Markdown (:func:`diagnosis_report` without records), linking the figure files
    ``figure`` (:func:`plot_residuals`) and ``trace_figure`` (:func:`plot_trace`) when given."""
    text = diagnosis_report(diagnosis).markdown()
    links = [f"![residuals]({figure})"] if figure else []
    links += [f"![residual against its strongest variables]({trace_figure})"] if trace_figure else []
    return text + "".join(f"\n{link}\n" for link in links)


#: a traced variable explaining less than this share of a residual's validation variance says nothing
LEAST_SHARE = 0.05


def diagnosis_report(diagnosis: Diagnosis, *, train: Measurements | None = None,
                     validation: tuple[Comparison, Comparison] | None = None,
                     test: tuple[Comparison, Comparison] | None = None, validate: Measurements | None = None,
                     preprocessing: str | None = None, warnings: Sequence[str] = (),
                     test_errors: dict[str, Any] | None = None, test_note: str | None = None,
                     answer: dict[str, Any] | None = None) -> Report:
    """The report a person reads, built once for Markdown and HTML (:class:`~dynamics.runtime.report_document.Report`).

    Parameters
    ----------
    diagnosis
        The diagnosis.
    train, validate
        The prepared training and validation records (the residual figure, the tracing figure), or ``None``.
    validation, test
        ``(before, after)`` comparisons against the channels as recorded on the validation and the test record:
        a measured-against-predicted figure per channel each, or ``None``.
    preprocessing
        The preprocessing chosen, in one line.
    warnings
        Every warning of the run.
    test_errors
        ``UntouchedErrors.to_dict()`` of the test record, or ``None`` (then ``test_note`` says why it matters).
    answer
        ``report.json`` as the verb writes it: the model it chose (``validation.chosen``, ``test.chosen``,
        ``model_selection``), the one ``oed predict`` uses and ``oed export`` writes, and its errors
        (:func:`answer_blocks`); ``None``: no such section.
    """
    document = diagnosis.to_dict()
    blocks: list[Block] = [Paragraph(f"Declared effects: {', '.join(f'`{e}`' for e in document['declared_effects']) or 'none'}.")]
    blocks.append(Paragraph("Errors are mean squared errors against the channels as recorded, at the recorded time "
                            "stamps."))
    warnings = tuple(dict.fromkeys([*warnings, *document["warnings"]["after"]]))  # the estimate's own too
    blocks += [Heading("Warnings"), Bullets(warnings) if warnings else Paragraph("None.")]
    blocks += effect_blocks(document)
    blocks += choice_blocks(diagnosis, document, preprocessing)
    blocks += parameter_blocks(diagnosis)
    if document.get("pinned"):
        blocks += [Heading("Terms held at zero (a friction or inertia may not be negative)"),
                   Bullets(tuple(f"{term['parameter']} ({term['effect']}{', found' if term['found'] else ''}): "
                                 f"{term['reason']}" for term in document["pinned"]))]
    blocks += error_blocks(document)
    blocks += answer_blocks(answer)
    if test_errors is not None:
        blocks += test_blocks(test_errors)
    elif test_note:
        blocks.append(Paragraph(test_note))
    for label, pair in (("validation", validation), ("test", test)):
        if pair is not None:
            blocks += comparison_blocks(label, *pair)
    blocks += statistics_blocks(document)
    if validate is not None and diagnosis.statistics is not None:
        blocks += trace_blocks(diagnosis, validate)
    blocks += residual_blocks(document)
    if train is not None and validate is not None and diagnosis.statistics is not None:
        traced = tuple(telling_rows(diagnosis.statistics.tracing["before"], validate))
        if traced:
            blocks.append(ReportFigure(
                "residuals", f"Training residuals of the declared model on {', '.join(traced)} (the channels whose "
                "validation residual follows a traced variable) against q, dq, ddq of their joint and time",
                functools.partial(plot_residuals, diagnosis, train, channels=traced)))
    absorbed = [r for r in document["rejected"] if "absorb" in r["reason"]]
    if absorbed:
        blocks += [Heading("Not identifiable here"),
                   Bullets(tuple(f"{r['name']} on {', '.join(r['channels'])}: {r['reason']}" for r in absorbed))]
    return Report(f"Diagnosis: {document['robot']}, {document['model']} model", tuple(blocks))


def effect_blocks(document: dict[str, Any]) -> list[Block]:
    """The effects found with their estimates."""
    blocks: list[Block] = [Heading("Effects found")]
    if not document["effects"]:
        return blocks + [Paragraph("Nothing significant that also lowers the validation error: the declared model "
                                   "is enough.")]
    rows = []
    for effect in document["effects"]:
        label = effect.get("spec", effect["name"])
        shape = effect.get("shape", {})
        values = list(zip(effect["parameters"], effect["values"], effect["std"]))
        values += [(f"{name} (shape)", value, effect["shape_std"][name]) for name, value in shape.items()]
        rows += [(label, ", ".join(effect["channels"]), name, f"{value:.5g}", f"{std:.2g}", f"{effect['p_value']:.2g}")
                 for name, value, std in values]
    return blocks + [Table(("effect", "channels", "parameter", "value", "std", "p-value"), tuple(rows))]


def choice_blocks(diagnosis: Diagnosis, document: dict[str, Any], preprocessing: str | None) -> list[Block]:
    """The choices made: preprocessing, weighting, effects adopted and rejected, the runner-up."""
    estimate = diagnosis.after.estimate
    items = [preprocessing] if preprocessing else []
    items.append(f"estimator: {estimate.method}; standard deviations: {diagnosis.cov_method}")
    items.append("adopted: " + (", ".join(f"{e.get('spec', e['name'])} on {', '.join(e['channels'])} "
                                         f"(p = {e['p_value']:.2g})" for e in document["effects"]) or "nothing"))
    items.append(runner_up_line(diagnosis.runner_up, diagnosis.runner_up_reason))
    blocks: list[Block] = [Heading("Choices made"), Bullets(tuple(items))]
    if document["rejected"]:
        blocks += [Heading("Candidates rejected", 3),
                   Paragraph("A reason's validation error (a -> b) is the one the search compares: the sum over the "
                             "channels of each channel's validation MSE times its channel weight (the inverse "
                             "variance of its training residual), without the candidate and with it; not the MSE "
                             "of the tables below."),
                   Table(("candidate", "channels", "reason"),
                         tuple((r["spec"], ", ".join(r["channels"]), r["reason"]) for r in document["rejected"]))]
    return blocks


def parameter_blocks(diagnosis: Diagnosis) -> list[Block]:
    """The diagnosed model's base parameters with their standard deviations."""
    return [Heading("Parameters of the diagnosed model"),
            Paragraph(f"Standard deviations: {diagnosis.cov_method}; condition number "
                      f"{float(diagnosis.after.estimate.cond):.3g}."),
            parameter_table(diagnosis.after)]


def error_blocks(document: dict[str, Any]) -> list[Block]:
    """The validation error per channel before and after."""
    before, after = document["validation"]["before"]["mse"], document["validation"]["after"]["mse"]
    rows = tuple((channel, f"{value:.5g}", f"{after[channel]:.5g}", f"{after[channel] / value if value else np.nan:.3f}")
                 for channel, value in before.items())
    return [Heading("Validation error per channel (held-out data)"),
            Table(("channel", "MSE before", "MSE after", "ratio"), rows)]


def answer_blocks(document: dict[str, Any] | None) -> list[Block]:
    """The model the verb chose (``report.json``'s ``validation.chosen``, ``test.chosen`` and ``model_selection``):
    its name, why, and its errors on the validation and test records, what ``oed predict`` gives there."""
    chosen = None if document is None else (document.get("validation") or {}).get("chosen")
    if chosen is None or chosen.get("mse") is None:
        return []
    reason = (document.get("model_selection") or {}).get("reason")
    test = (document.get("test") or {}).get("chosen")
    head = ("channel", "validation MSE") + (("test MSE",) if test is not None else ())
    rows = tuple((channel, f"{value:.5g}") + ((f"{test['mse'][channel]:.5g}",) if test is not None else ())
                 for channel, value in chosen["mse"].items())
    return [Heading("The answer: the model `oed predict` uses and `oed export` writes"),
            Paragraph(f"Model: {chosen['name']}" + (f" ({reason})" if reason else "") + "."), Table(head, rows)]


def test_blocks(errors: dict[str, Any]) -> list[Block]:
    """The test record's error before and after (``UntouchedErrors.to_dict()``)."""
    ratios = errors["after"]["mse_over_floor"] or {}
    rows = tuple((channel, f"{errors['before']['mse'][channel]:.4g}", f"{value:.4g}",
                  f"{ratios[channel]:.3g}" if channel in ratios else "n/a")
                 for channel, value in errors["after"]["mse"].items())
    return [Heading("Test record (no choice used it)"),
            Table(("channel", "MSE before", "MSE after", "after / floor"), rows)]


def comparison_blocks(label: str, before: Comparison, after: Comparison) -> list[Block]:
    """A figure per channel: measured against predicted before and after, and the residuals, on record ``label``."""
    n = before.t.shape[0]
    step = subsample_step(n)
    drawn = f"every {step}th of {n} samples" if step > 1 else f"all {n} samples"
    blocks: list[Block] = [Heading(f"Measured against predicted ({label} record)"),
                           Paragraph(f"Torques as recorded, at the recorded time stamps ({drawn} drawn); the "
                                     "declared model (before) and the diagnosed one (after).")]
    for row, channel in enumerate(before.channels):
        blocks.append(ReportFigure(f"{label}.{channel}", f"{channel} on the {label} record: measured, before, after, "
                             "and the residuals", functools.partial(plot_before_after, before, after, row, step,
                                                                    f"{channel}, {label} record")))
    return blocks


def plot_before_after(before: Comparison, after: Comparison, row: int, step: int = 1, title: str = "") -> Figure:
    """Channel ``row``: measured, predicted before and after (top) and both residuals (bottom) against time,
    every ``step``-th sample (:func:`~estimation.identification.validation.plot_channel`)."""
    return plot_channel({"before": before, "after": after}, row, step, title)


def statistics_blocks(document: dict[str, Any]) -> list[Block]:
    """The noise floor, the floor comparison, the tracing table and the whiteness checks of a report."""
    if "noise_floor" not in document:
        return []
    floor = document["noise_floor"]
    blocks: list[Block] = [Heading("Noise floor"), Paragraph(f"Method: {floor.get('method', 'none')} ({floor['note']}).")]
    if floor["mse"] is not None:
        comparison = document["floor_comparison"]
        rows = []
        for channel, value in floor["mse"].items():
            before, after = comparison["before"][channel], comparison["after"][channel]
            verdict = f"{after['ratio']:.3g} x above" if after["above"] else "at its floor"
            rows.append((channel, f"{value:.4g}", f"{before['ratio']:.3g}", f"{after['ratio']:.3g}", verdict))
        blocks.append(Table(("channel", "floor (MSE)", "MSE / floor before", "MSE / floor after", ""), tuple(rows)))
    if document.get("floor_statements"):
        blocks.append(Bullets(tuple(document["floor_statements"].values())))
    tracing = document["tracing"]
    if tracing is None or document["whiteness"] is None:  # the streamed path holds no residuals sample by sample
        return blocks + not_computed_blocks(document, ("tracing", "whiteness"))

    def strongest(which: str, channel: str) -> str:
        rows = [row for row in tracing[which]["rows"] if row["channel"] == channel
                and row["validation_share"] >= LEAST_SHARE][:3]
        return ", ".join(f"{row['variable']} {100 * row['validation_share']:.0f} %" for row in rows) or \
            f"none above {100 * LEAST_SHARE:g} %"

    channels = list(dict.fromkeys(row["channel"] for row in tracing["after"]["rows"]))
    blocks += [Heading("What the residual follows (share of the validation variance explained by binned means "
                       "fitted on training)"),
               Table(("channel", "before: strongest variables", "after: strongest variables"),
                     tuple((channel, strongest("before", channel), strongest("after", channel)) for channel in channels))]
    whiteness = document["whiteness"]
    rows = []
    for channel, check in whiteness["after"]["channels"].items():
        before = whiteness["before"]["channels"][channel]["whiteness"]
        correlated = [name for name, entry in check["inputs"].items() if not entry["passed"]]
        rows.append((channel, f"{before['outside']}/{len(before['lags'])}",
                     f"{check['whiteness']['outside']}/{len(check['whiteness']['lags'])}",
                     f"{check['whiteness']['values'][0]:.2f}", ", ".join(correlated) or "none"))
    return blocks + [
        Heading(f"Whiteness and input correlation of the validation residual "
                f"({100 * whiteness['after']['confidence']:g} % bands)"),
        Table(("channel", "lags outside (before)", "lags outside (after)", "lag-1 autocorrelation after",
               "correlated with (after)"), tuple(rows))]


def trace_blocks(diagnosis: Diagnosis, validate: Measurements) -> list[Block]:
    """The tracing figure when a traced variable explains at least :data:`LEAST_SHARE` of a residual, else a
    sentence saying the residual follows none."""
    if diagnosis.statistics is None:
        return []
    trace = diagnosis.statistics.tracing["after"]
    if not telling_rows(trace, validate):
        return [Paragraph(f"After the diagnosis no traced variable explains {100 * LEAST_SHARE:g} % or more of any "
                          "channel's validation residual: no tracing figure.")]
    return [ReportFigure("trace", "Residual after the diagnosis (validation) against the variables that explain at least "
                   f"{100 * LEAST_SHARE:g} % of it", functools.partial(plot_trace, diagnosis, validate))]


def telling_rows(trace: ResidualTrace, validate: Measurements, count: int = 3) -> dict[str, tuple[TraceRow, ...]]:
    """Per channel, its strongest ``count`` traced variables that explain at least :data:`LEAST_SHARE` of the
    validation residual, without a variable whose values repeat one already kept; channels with none left out."""
    variables = state_variables(validate)
    kept: dict[str, tuple[TraceRow, ...]] = {}
    for channel in trace.channels():
        rows: list[TraceRow] = []
        for row in trace.rows:
            if row.channel != channel or not row.validation_share >= LEAST_SHARE or len(rows) == count:
                continue
            values = variables.get(row.variable)
            if any(row.variable == other.variable or (values is not None and np.array_equal(
                    values, variables.get(other.variable))) for other in rows):
                continue
            rows.append(row)
        if rows:
            kept[channel] = tuple(rows)
    return kept


def not_computed_blocks(document: dict[str, Any], keys: Sequence[str]) -> list[Block]:
    """What the path did not compute of ``keys``, and why (the document's ``not_computed``)."""
    missing = document.get("not_computed") or {}
    reasons = tuple(f"{key}: {missing[key]}" for key in keys if key in missing)
    return [Heading("Not computed on this path"), Bullets(reasons)] if reasons else []


def residual_blocks(document: dict[str, Any]) -> list[Block]:
    """The declared model's training residual statistics."""
    if document["residuals"] is None:
        return not_computed_blocks(document, ("residuals",))
    rows = []
    for channel, stats in document["residuals"].items():
        autocorrelation = " / ".join(f"{stats[key]:.2f}" for key in stats if key.startswith("autocorrelation"))
        rows.append((channel, f"{stats['mean']:.4g}", f"{stats['std']:.4g}", autocorrelation))
    return [Heading("Residual statistics of the declared model (training)"),
            Table(("channel", "mean", "std", "autocorrelation lag 1 / 10 / 100"), tuple(rows))]


def plot_trace(diagnosis: Diagnosis, validate: Measurements, path: str | Path | None = None) -> Figure | None:
    """The augmented model's validation residual against the variables that say something about it
    (:func:`telling_rows`); ``None`` without statistics or without such a variable."""
    if diagnosis.statistics is None:
        return None
    trace = diagnosis.statistics.tracing["after"]
    kept = telling_rows(trace, validate)
    if not kept:
        return None
    channels = diagnosis.after.estimate.channels
    rows = tuple(row for channel in channels for row in kept.get(channel, ()))
    residuals = np.asarray(diagnosis.after.validation.residuals, dtype=float).reshape(-1, len(channels))
    if residuals.shape[0] != validate.n_samples:
        # errors against the record as recorded: a jittered or stalled log's residuals are on its recorded samples,
        # not on the uniform grid it was prepared on (the Panda's validation record: 3110 against 3360)
        validate = validate.as_recorded
    if residuals.shape[0] != validate.n_samples:
        raise ValueError(f"the validation residual holds {residuals.shape[0]} samples, the record {validate.n_samples}")
    columns = [channels.index(channel) for channel in kept]
    return plot_residual_trace(replace(trace, rows=rows), residuals[:, columns], validate, tuple(kept), path,
                               count=max(len(value) for value in kept.values()),
                               title="Residual after the diagnosis (validation) against its strongest variables")
