"""The report a user reads (``oed diagnose --report x.html|x.md``): one document built once, written as a
self-contained HTML page (figures inline) or as Markdown (figures beside it); the tracing figure only where the
tracing says something."""

from __future__ import annotations

import base64
import shutil
import subprocess
from html.parser import HTMLParser

import numpy as np
import pytest

import oed
from dynamics.effects.linear import CoulombFriction
from dynamics.models import build_model
from dynamics.robots import load_robot
from dynamics.runtime.report_document import Figure, Heading, Paragraph, Report, Table
from dynamics.simulation.synthetic import simulate, true_parameters
from estimation.diagnosis.report import LEAST_SHARE, telling_rows
from estimation.uncertainty.residual_tracing import ResidualTrace, TraceRow
from oed.cli import main
from oed.fourier import random_fourier


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    folder = tmp_path_factory.mktemp("report")
    robot = load_robot("puma560", joints=3)
    truth = build_model(robot, "internal", ("viscous", CoulombFriction(joints=(1,))))
    theta = true_parameters(truth, seed=0, coulomb=[8.0])
    noise = {channel: 0.2 for channel in truth.channels}
    for k, name in enumerate(("train", "validate", "test")):
        simulate(truth, theta, random_fourier(robot, seed=3 + k), noise=noise, seed=1 + k,
                 periods=2).write(folder / f"{name}.csv")
    return folder


class Page(HTMLParser):
    """The tags, the inline images and the text of an HTML page."""

    def __init__(self) -> None:
        super().__init__()
        self.tags: list[str] = []
        self.images: list[bytes] = []
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)
        source = dict(attrs).get("src")
        if tag == "img":
            assert source.startswith("data:image/png;base64,"), source[:40]  # nothing outside the file
            self.images.append(base64.b64decode(source.split(",", 1)[1]))

    def handle_data(self, data):
        self.text.append(data)


def parse(text: str) -> Page:
    page = Page()
    page.feed(text)
    page.close()
    return page


def test_the_html_report_is_one_page_with_its_tables_and_inline_figures(records, capsys):
    report = records / "report.html"
    code = main(["diagnose", "--joints", "3", "--data", str(records / "train.csv"), "--validate",
                 str(records / "validate.csv"), "--test", str(records / "test.csv"), "--frequency", "0.2",
                 "--out", str(records / "report.json"), "--report", str(report)])
    assert code == 0, capsys.readouterr().err
    page = parse(report.read_text())
    text = " ".join(page.text)
    # residuals of the declared model (tau2 follows dq2) + measured against predicted per channel, validation and test
    assert len(page.images) == 1 + 3 + 3
    assert all(image.startswith(b"\x89PNG") for image in page.images)
    for heading in ("Effects found", "Choices made", "Parameters of the diagnosed model",
                    "Validation error per channel", "Test record (no choice used it)", "Noise floor",
                    "Measured against predicted (validation record)", "Measured against predicted (test record)"):
        assert heading in text
    assert page.tags.count("table") >= 6
    assert "fc2" in text and "runner-up" in text
    # after the Coulomb friction is added no traced variable explains anything: no tracing figure, no "0 %" panel
    assert "no tracing figure" in text and " 0 %" not in text
    assert sorted(path.name for path in records.iterdir() if path.name.startswith("report.")) == \
        ["report.html", "report.json"]  # nothing beside it


def test_markdown_and_html_are_the_same_document(records):
    run = oed.diagnose(joints=3, data=records / "train.csv", validate=records / "validate.csv", frequency=0.2,
                       report=True)
    document = run.report()
    run.write(records / "same.json", report=records / "same.md")
    markdown = (records / "same.md").read_text()
    assert markdown == run.markdown(records / "same.md")
    names = [figure.name for figure in document.figures()]
    assert names == ["validation.tau1", "validation.tau2", "validation.tau3", "residuals"]
    for name in names:
        assert (records / f"same.{name}.png").exists() and f"(same.{name}.png)" in markdown
    assert not (records / "same.trace.png").exists()
    assert markdown.count("\n| channel |") + markdown.count("\n| effect |") + markdown.count("\n| parameter |") \
        + markdown.count("\n| candidate |") == len(document.tables())
    assert "Give `--test FILE`" in markdown
    assert "<code>--test FILE</code>" in run.html()


def test_a_report_of_another_format_is_refused_before_any_work(tmp_path, capsys):
    code = main(["diagnose", "--data", str(tmp_path / "missing.csv"), "--validate", str(tmp_path / "v.csv"),
                 "--out", str(tmp_path / "r.json"), "--report", str(tmp_path / "r.pdf")])
    error = capsys.readouterr().err
    assert code == 2 and "--report" in error and ".html" in error and "missing.csv" not in error


def test_the_tracing_figure_keeps_only_variables_that_say_something(records):
    from estimation.data.records import read_measurements

    validate = read_measurements(records / "validate.csv", n_joints=3)
    rows = (TraceRow("tau1", "dq1", 0.4, 0.5), TraceRow("tau1", "dq1", 0.4, 0.5),  # the same panel twice
            TraceRow("tau1", "q1", 0.02, 0.01),                                       # "1 %": says nothing
            TraceRow("tau2", "dq2", 0.0, 0.0), TraceRow("tau2", "q2", 0.0, -0.1))     # nothing at all
    kept = telling_rows(ResidualTrace(rows, bins=10), validate)
    assert list(kept) == ["tau1"] and [row.variable for row in kept["tau1"]] == ["dq1"]
    assert all(row.validation_share >= LEAST_SHARE for rows in kept.values() for row in rows)


def test_a_report_renders_text_as_text():
    report = Report("a <b> & c", (Heading("x|y"), Paragraph("`<code>` & more"), Table(("a|b",), (("1",),)),
                                   Figure("f", "caption", lambda: None)))
    text = report.markdown(lambda figure: "f.png")
    assert "| a\\|b |" in text and "![caption](f.png)" in text
    page = Report(report.title, report.blocks[:3]).html()
    assert "<h1>a &lt;b&gt; &amp; c</h1>" in page and "<code>&lt;code&gt;</code> &amp; more" in page


CHROMIUM = next((shutil.which(name) for name in ("chromium", "chromium-browser", "google-chrome")
                 if shutil.which(name)), None)


@pytest.mark.skipif(CHROMIUM is None, reason="no chromium on this machine: the headless check needs it")
def test_the_html_report_opens_in_a_headless_browser(records, tmp_path):
    report = records / "report.html"
    if not report.exists():  # the other test wrote it when both run in this process; under xdist, write it here
        assert main(["diagnose", "--joints", "3", "--data", str(records / "train.csv"), "--validate",
                     str(records / "validate.csv"), "--frequency", "0.2", "--out", str(records / "report.json"),
                     "--report", str(report)]) == 0
    shot = tmp_path / "report.png"
    completed = subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                                f"--screenshot={shot}", "--window-size=1200,3000", report.as_uri()],
                               capture_output=True, timeout=120, check=False)
    assert shot.exists(), completed.stderr.decode(errors="replace")[-2000:]
    from matplotlib.image import imread

    pixels = imread(shot)
    assert pixels.shape[0] >= 1000 and np.std(pixels[..., :3]) > 0.05  # drawn, not a blank page


def test_predict_plots_measured_against_predicted_with_the_residual(records, capsys):
    model, figure = records / "model.json", records / "predicted.png"
    oed.identify(joints=3, friction="viscous,coulomb", data=records / "train.csv",
                 validate=records / "validate.csv").write(model)
    assert main(["predict", "--model", str(model), "--data", str(records / "test.csv"), "--plot", str(figure)]) == 0
    assert figure.read_bytes().startswith(b"\x89PNG") and f"wrote {figure}" in capsys.readouterr().out
    drawn = oed.predict(model=model, data=records / "test.csv").plot()
    assert len(drawn.axes) == 2 * 3  # per channel: measured and predicted with the band, then the residual
    code = main(["predict", "--model", str(model), "--data", str(records / "missing.csv"), "--plot",
                 str(records / "predicted.xyz")])
    assert code == 2 and "xyz" in capsys.readouterr().err and not (records / "predicted.xyz").exists()


def test_identify_writes_its_report_in_either_format(records, capsys):
    out = records / "result.json"
    arguments = ["identify", "--joints", "3", "--friction", "viscous,coulomb", "--data", str(records / "train.csv"),
                 "--validate", str(records / "validate.csv"), "--out", str(out)]
    assert main([*arguments, "--report", str(records / "identified.html")]) == 0
    assert f"and {records / 'identified.html'}" in capsys.readouterr().out
    page = parse((records / "identified.html").read_text())
    text = " ".join(page.text)
    assert len(page.images) == 3 and "Parameters" in text and "fc2" in text and "Error per channel" in text
    assert main([*arguments, "--report", str(records / "identified.md")]) == 0
    markdown = (records / "identified.md").read_text()
    assert "(identified.validation.tau2.png)" in markdown and (records / "identified.validation.tau2.png").exists()
    assert main([*arguments, "--report", str(records / "identified.pdf")]) == 2
    assert "--report" in capsys.readouterr().err


def test_the_tracing_figure_shows_only_the_channel_whose_residual_follows_a_variable(records):
    from estimation.data.records import read_measurements
    from estimation.diagnosis.report import diagnosis_report
    from estimation.diagnosis.search import diagnose

    robot = load_robot("puma560", joints=3)
    train = read_measurements(records / "train.csv", n_joints=3)
    validate = read_measurements(records / "validate.csv", n_joints=3)
    diagnosis = diagnose(build_model(robot, "internal", "viscous"), train, validate, candidates=[])  # Coulomb missed
    kept = telling_rows(diagnosis.statistics.tracing["after"], validate)
    assert list(kept) == ["tau2"] and kept["tau2"][0].variable in ("dq2", "sign_dq2")
    report = diagnosis_report(diagnosis, train=train, validate=validate)
    names = [figure.name for figure in report.figures()]
    assert names == ["trace", "residuals"]
    drawn = report.figures()[0].draw()
    titles = [axis.get_title() for axis in drawn.axes if axis.get_title()]
    assert titles and all(title.startswith("tau2: ") and not title.startswith("tau2: 0 %") for title in titles)
    assert len(set(titles)) == len(titles)  # no panel twice


def test_the_tracing_figure_of_a_jittered_validation_record_is_drawn_on_its_recorded_samples(records, tmp_path):
    """A jittered log is prepared on a uniform grid, but its validation errors are taken on the samples as recorded
    (2000 here, against 2010 grid samples): the tracing figure plots those residuals against the recorded samples'
    motion. It raised ``cannot reshape array`` and `oed diagnose --report` exited on the Panda's real log."""
    import pandas as pd

    from estimation.data.loading import ReceiveTimesWarning, ResampledWarning
    from estimation.data.records import read_measurements
    from estimation.diagnosis.report import diagnosis_report
    from estimation.diagnosis.search import diagnose

    frame = pd.read_csv(records / "validate.csv")
    step = float(np.diff(frame["t"]).mean())
    frame["t"] = frame["t"] + np.random.default_rng(0).uniform(-0.2, 0.2, len(frame)) * step
    frame.to_csv(tmp_path / "validate_jittered.csv", index=False)
    robot = load_robot("puma560", joints=3)
    train = read_measurements(records / "train.csv", n_joints=3)
    # the samples where they were, the stamps moved: the reader also says they look like receive times
    with pytest.warns(ReceiveTimesWarning), pytest.warns(ResampledWarning, match="irregular sampling"):
        validate = read_measurements(tmp_path / "validate_jittered.csv", n_joints=3)
    assert validate.recorded is not None and validate.recorded.n_samples == len(frame) != validate.n_samples
    diagnosis = diagnose(build_model(robot, "internal", "viscous"), train, validate, candidates=[])  # Coulomb missed
    assert np.asarray(diagnosis.after.validation.residuals).shape == (len(frame), 3)
    report = diagnosis_report(diagnosis, train=train, validate=validate)
    assert [figure.name for figure in report.figures()][0] == "trace"
    drawn = report.figures()[0].draw()
    assert any(axis.get_title().startswith("tau2: ") for axis in drawn.axes)
