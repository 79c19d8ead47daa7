"""Prints what the docs test checked (counts, slow and skipped blocks) at the end of the run."""

from tests.docs.report import REPORT


def pytest_terminal_summary(terminalreporter):
    for line in REPORT.lines():
        terminalreporter.write_line(line)
