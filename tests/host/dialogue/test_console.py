"""The questions of the live dialogue on a scripted console: an Enter typed with a one-key
answer is not the next question's answer (issue 46: "y⏎" at a Y/N question left the next
prompt, "Accumulation time … seconds", an empty answer)."""

from __future__ import annotations

from host.dialogue.console import Questions, ScriptedConsole


def questions(keys: str, grace: float = 10.0) -> tuple[Questions, ScriptedConsole]:
    """A script's keys come at once, so with a grace of 10 s every Enter right after a
    one-key answer counts as typed with it."""
    con = ScriptedConsole([keys], stray_enter_s=grace)
    return Questions(con), con


def test_an_enter_typed_with_a_yes_is_not_the_next_answer() -> None:
    q, _ = questions("y\r2\r")
    assert q.yes_no("Measure the faces <Y> or go to the turns <N>?", default=False) is True
    assert q.read_line("Accumulation time, seconds: ") == "2"


def test_an_enter_typed_with_a_key_does_not_start_the_next_measurement() -> None:
    """Save <Y> then Enter: the next "Press any key" waits for its own key."""
    q, _ = questions("y\r P2\r")
    assert q.yes_no("Save <Y> or repeat <N>?", default=True) is True
    assert q.any_key("Put the cube with X down. Press any key.") == " "
    assert q.read_line("Serial: ") == "P2"


def test_only_one_enter_is_dropped_and_only_after_a_one_key_answer() -> None:
    q, _ = questions("n\r\r\r")
    assert q.yes_no("Save <Y> or repeat <N>?", default=True) is False
    assert q.yes_no("Next?", default=True) is True  # the second Enter is an answer
    assert q.yes_no("Again?", default=False) is False  # an Enter answered: nothing dropped


def test_an_enter_after_the_grace_is_an_answer() -> None:
    q, _ = questions("y\r", grace=0.0)
    assert q.yes_no("Measure the faces?", default=True) is True
    assert q.read_line("Accumulation time, seconds: ") == ""


def test_a_line_or_a_key_keeps_the_enter_after_it() -> None:
    """A line ends with its own Enter, and the key that starts a measurement is followed by
    the measurement: the next question's Enter is its answer."""
    q, _ = questions("P1\r\r \r")
    assert q.read_line("Serial: ") == "P1"
    assert q.yes_no("Measure the faces?", default=False) is False
    assert q.any_key("Put the cube with X up. Press any key.") == " "
    assert q.yes_no("Save <Y> or repeat <N>?", default=True) is True


def test_a_wrong_key_then_yes_still_drops_the_enter_after_it() -> None:
    q, con = questions("xy\r5\r")
    assert q.yes_no("Save <Y> or repeat <N>?", default=False) is True
    assert "press Y or N" in con.text
    assert q.read_line("Seconds: ") == "5"
