"""Terminal I/O of the live calibration dialogue: keys, prompts, beep, progress line.

Two layers:

* a :class:`Console` — the raw device: ``write`` text, read one ``key`` with a timeout, ``beep``,
  a transient ``progress`` line. :class:`TerminalConsole` is the real terminal (keys in cbreak
  mode from the controlling tty, text on stderr); :class:`ScriptedConsole` plays a list of keys
  and records the screen, for unit tests.
* :class:`Questions` — the questions the dialogue asks the operator (a line of text, Y/N, any
  key, a countdown), built on a console. While it waits for the human it calls ``idle()``
  about every ``poll_s`` seconds, so the program keeps reading the board. With ``yes=True``
  it never reads a key: every question gets its default (works with stdin closed).

Keys are strings: one character, ``ESC`` for a lone Esc, ``"\\r"`` for Enter; escape sequences
(arrow keys…) come as one string starting with ESC + "[" and count as "any key". Ctrl+C is the
terminal's SIGINT (cbreak keeps ISIG), i.e. ``KeyboardInterrupt``; a 0x03 byte read in raw mode
raises it too. SIGTERM (a service manager, ``kill``) and SIGHUP (the terminal closed) end a
session the same way, as :class:`EndedBySignal` (:func:`signals_end_like_ctrl_c`).

An Enter typed with a one-key answer ("y⏎" at a Y/N question) is not the next question's
answer: an Enter already typed when the next question is shown, or typed within
:data:`STRAY_ENTER_S` of the one-key answer, is dropped (a measurement after the question
drops every key but Esc anyway).
"""

from __future__ import annotations

import contextlib
import os
import select
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from typing import Protocol, TextIO, TypeVar

from host.errors import UserError

ESC = "\x1b"
CTRL_C = "\x03"
ENTER = "\r"
BACKSPACES = ("\x7f", "\x08")
BEEP_MARK = "*** BEEP ***"
ENTERS = ("\r", "\n")
#: an Enter this soon (s) after a one-key answer was typed with it: nobody reads the next
#: question and answers it with Enter that fast
STRAY_ENTER_S = 0.3

T = TypeVar("T")


class Console(Protocol):
    """What the dialogue needs from a terminal."""

    #: False: no keys can be read (``--yes`` mode, no terminal)
    interactive: bool

    @property
    def columns(self) -> int:
        """Width of the screen, characters (a progress line must stay shorter)."""

    def write(self, text: str) -> None:
        """Write text as is (no newline added)."""

    def say(self, text: str = "") -> None:
        """Write one line (ends a progress line first)."""

    def beep(self) -> None:
        """Terminal bell plus a visible marker (silent terminals)."""

    def progress(self, text: str) -> None:
        """Show a transient status line (overwritten by the next one)."""

    def end_progress(self) -> None:
        """Finish the progress line, if one is shown."""

    def key(self, timeout_s: float) -> str | None:
        """One key, waiting at most ``timeout_s`` seconds (0: just look); None if none."""


# --------------------------------------------------------------------------- real terminal


class EndedBySignal(KeyboardInterrupt):
    """SIGTERM or SIGHUP ended the program: handled as Ctrl+C is. ``name`` ('SIGTERM') and
    the shell's exit status for it, 128 + the signal number (143, 129)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.name = signal.Signals(signum).name
        self.exit_status = 128 + signum


@contextlib.contextmanager
def signals_end_like_ctrl_c() -> Iterator[None]:
    """While inside: the first SIGTERM or SIGHUP raises :class:`EndedBySignal` in the main
    thread (where Ctrl+C's KeyboardInterrupt is raised); later ones are ignored while the
    program winds up. The previous handlers are restored on exit."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    fired = False

    def end(signum: int, _frame: object) -> None:
        nonlocal fired
        if not fired:
            fired = True
            raise EndedBySignal(signum)

    wanted = [s for s in ("SIGTERM", "SIGHUP") if hasattr(signal, s)]
    old = {s: signal.signal(getattr(signal, s), end) for s in wanted}
    try:
        yield
    finally:
        for s, handler in old.items():
            signal.signal(getattr(signal, s), handler)


class TerminalConsole:
    """The real terminal: text on ``out`` (default stderr), keys from the controlling tty.

    ``interactive=False`` never touches the keyboard (for ``--yes``). Use as a context manager:
    the terminal mode is restored on exit, also after Ctrl+C.
    """

    def __init__(self, interactive: bool, out: TextIO | None = None) -> None:
        self.interactive = interactive
        self.out = out if out is not None else sys.stderr
        self._is_tty = bool(getattr(self.out, "isatty", lambda: False)())
        self._fd: int | None = None
        self._own_fd = False
        self._saved: list | None = None  # type: ignore[type-arg]
        self._buf = b""
        self._progress_on = False
        self._last_progress = 0.0

    # ---- terminal mode -------------------------------------------------------------------
    def open(self) -> TerminalConsole:
        """Put the keyboard into cbreak mode (no line editing, no echo; Ctrl+C still works)."""
        if not self.interactive or self._fd is not None:
            return self
        import termios
        import tty

        fd: int | None = None
        try:
            if sys.stdin is not None and sys.stdin.isatty():
                fd = sys.stdin.fileno()
            else:
                fd = os.open("/dev/tty", os.O_RDONLY | getattr(os, "O_NOCTTY", 0))
                self._own_fd = True
        except (OSError, ValueError):
            fd = None
        if fd is None:
            raise UserError(
                "the calibration dialogue needs a terminal for the keys; run it in a terminal, "
                "or use --yes for a non-interactive run"
            )
        self._fd = fd
        self._saved = termios.tcgetattr(fd)
        tty.setcbreak(fd, termios.TCSANOW)
        return self

    def close(self) -> None:
        """Restore the terminal mode."""
        self.end_progress()
        if self._fd is None:
            return
        import termios

        try:
            if self._saved is not None:
                termios.tcsetattr(self._fd, termios.TCSADRAIN, self._saved)
        except OSError:
            pass
        if self._own_fd:
            try:
                os.close(self._fd)
            except OSError:
                pass
        self._fd = None

    def __enter__(self) -> TerminalConsole:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- output --------------------------------------------------------------------------
    @property
    def columns(self) -> int:
        """The terminal's width now (it may be resized); COLUMNS or 80 when unknown."""
        if self._is_tty:
            try:
                cols = os.get_terminal_size(self.out.fileno()).columns
                if cols > 0:
                    return cols
            except (OSError, ValueError):
                pass
        try:
            return max(20, int(os.environ.get("COLUMNS", "80")))
        except ValueError:
            return 80

    def write(self, text: str) -> None:
        self.out.write(text)
        self.out.flush()

    def say(self, text: str = "") -> None:
        self.end_progress()
        self.write(text + "\n")

    def beep(self) -> None:
        self.say(f"\a{BEEP_MARK}")

    def progress(self, text: str) -> None:
        """On a terminal: redraw one line in place, cut to the width (a wrapped line could not
        be redrawn: every redraw would add a line). Otherwise (a log): a line every 5 s."""
        if self._is_tty:
            self.write("\r" + text[: self.columns - 1] + "\x1b[K")
            self._progress_on = True
            return
        now = time.monotonic()
        if now - self._last_progress >= 5.0:
            self._last_progress = now
            self.write(text + "\n")

    def end_progress(self) -> None:
        if self._progress_on:
            self._progress_on = False
            self.write("\n")
        self._last_progress = 0.0

    # ---- keys ----------------------------------------------------------------------------
    def key(self, timeout_s: float) -> str | None:
        if not self.interactive:
            return None
        if self._fd is None:
            self.open()
        assert self._fd is not None
        if not self._buf:
            r, _, _ = select.select([self._fd], [], [], max(0.0, timeout_s))
            if not r:
                return None
            self._read_more()
            if self._buf == ESC.encode():  # a lone Esc, or the start of a sequence?
                r, _, _ = select.select([self._fd], [], [], 0.03)
                if r:
                    self._read_more()
        return self._take_key()

    def _read_more(self) -> None:
        assert self._fd is not None
        data = os.read(self._fd, 64)
        if not data:  # the terminal went away
            raise KeyboardInterrupt
        self._buf += data

    def _take_key(self) -> str | None:
        buf = self._buf
        if not buf:
            return None
        if buf[0] == 0x03:  # Ctrl+C read as a byte (raw mode)
            self._buf = buf[1:]
            raise KeyboardInterrupt
        if buf[0] == 0x1B:
            if len(buf) > 1 and buf[1:2] in (b"[", b"O"):
                end = 2
                while end < len(buf) and not 0x40 <= buf[end] <= 0x7E:
                    end += 1
                end = min(end + 1, len(buf))
                self._buf = buf[end:]
                return buf[:end].decode("ascii", "replace")
            self._buf = buf[1:]
            return ESC
        lead = buf[0]
        n = 1 if lead < 0xC0 else 2 if lead < 0xE0 else 3 if lead < 0xF0 else 4
        self._buf = buf[n:]
        return buf[:n].decode("utf-8", "replace")


# --------------------------------------------------------------------------- scripted


class ScriptExhausted(AssertionError):
    """The dialogue asked for a key the script does not have (a test bug or a dialogue bug)."""


class ScriptedConsole:
    """A console for tests: plays ``keys`` (strings are split into single keys, so
    ``"S1\\r"`` types S, 1, Enter), records everything written in ``text``.

    Looking for a key without waiting (``key(0)``, what a measurement does to see Esc) only
    takes the next key if it is ESC or Ctrl+C; waiting for a key takes the next key, whatever
    it is. Ctrl+C (``"\x03"``) raises KeyboardInterrupt like the terminal's SIGINT.
    """

    interactive = True

    def __init__(
        self, keys: Iterable[str] = (), columns: int = 80, stray_enter_s: float = 0.0
    ) -> None:
        self.keys: list[str] = [c for k in keys for c in k]
        #: a script's keys come at once: 0 keeps every scripted Enter (Questions' grace)
        self.stray_enter_s = stray_enter_s
        self.text = ""
        self.beeps = 0
        self.columns = columns
        #: every progress line shown, in order
        self.progress_lines: list[str] = []

    def write(self, text: str) -> None:
        self.text += text

    def say(self, text: str = "") -> None:
        self.text += text + "\n"

    def beep(self) -> None:
        self.beeps += 1
        self.say(BEEP_MARK)

    def progress(self, text: str) -> None:
        self.progress_lines.append(text)

    def end_progress(self) -> None:
        pass

    def key(self, timeout_s: float) -> str | None:
        if timeout_s <= 0 and not (self.keys and self.keys[0] in (ESC, CTRL_C)):
            return None
        if not self.keys:
            tail = self.text[-400:]
            raise ScriptExhausted(f"the dialogue wants a key the script lacks; screen:\n{tail}")
        k = self.keys.pop(0)
        if k == CTRL_C:
            raise KeyboardInterrupt
        return k


# --------------------------------------------------------------------------- questions


class Questions:
    """The questions the dialogue asks the operator (the person at the bench), on a
    :class:`Console`.

    ``yes``: answer every question with its default without reading a key (a question
    without a default raises UserError naming the option to give). ``idle()`` is called about
    every ``poll_s`` seconds while waiting for the human (it keeps the board link read).
    """

    def __init__(
        self,
        console: Console,
        yes: bool = False,
        idle: Callable[[], None] | None = None,
        poll_s: float = 0.02,
    ) -> None:
        self.console = console
        self.yes = yes
        self.idle: Callable[[], None] = idle or (lambda: None)
        self.poll_s = poll_s
        #: how soon after a one-key answer an Enter counts as typed with it (s)
        self.stray_enter_s = float(getattr(console, "stray_enter_s", STRAY_ENTER_S))
        self._held: list[str] = []  # keys typed before a question was shown, for it
        self._one_key_at: float | None = None  # when the last one-key answer was typed

    # ---- output ----------------------------------------------------------------------------
    def say(self, text: str = "") -> None:
        self.console.say(text)

    def beep(self) -> None:
        self.console.beep()

    def progress(self, text: str) -> None:
        self.console.progress(text)

    @property
    def columns(self) -> int:
        """Width of the screen, characters."""
        return int(getattr(self.console, "columns", 80))

    def end_progress(self) -> None:
        self.console.end_progress()

    # ---- keys ------------------------------------------------------------------------------
    def _wait_key(self) -> str:
        while True:
            if self._held:
                return self._held.pop(0)
            self.idle()
            k = self.console.key(self.poll_s)
            if k is not None:
                return k

    def _key_now(self) -> str | None:
        """A key typed already (held or pending), without waiting; None if none."""
        return self._held.pop(0) if self._held else self.console.key(0.0)

    def _answered_by_one_key(self) -> None:
        """A one-key answer was just typed: an Enter typed with it is not the next answer."""
        self._one_key_at = time.monotonic()

    def _first_key(self) -> str:
        """The first key of a question just shown, past an Enter typed with the one-key
        answer before it: one already typed when the question was shown, or one typed within
        ``stray_enter_s`` of that answer."""
        since, self._one_key_at = self._one_key_at, None
        if since is None:
            return self._wait_key()
        while (k := self.console.key(0.0)) is not None:  # typed before this question
            self._held.append(k)
        if self._held and self._held[0] in ENTERS:
            self._held.pop(0)
            return self._wait_key()
        k = self._wait_key()
        if k in ENTERS and time.monotonic() - since < self.stray_enter_s:
            return self._wait_key()
        return k

    def escape_pressed(self) -> bool:
        """True if Esc was pressed (looked at without waiting; other keys are dropped)."""
        if self.yes or not self.console.interactive:
            return False
        while True:
            k = self._key_now()
            if k is None:
                return False
            if k == ESC:
                return True

    def key_pressed(self) -> bool:
        """True if any key (Esc too) was pressed, looked at without waiting: what the warm-up's
        "Press any key when ready" (method.md §5 step 3) listens for."""
        if self.yes or not self.console.interactive:
            return False
        return self._key_now() is not None

    def any_key(self, prompt: str) -> str:
        """Show ``prompt`` and wait for any key (returned; "" in --yes mode). Esc does not
        count: it aborts a measurement, and there is none yet to abort."""
        if self.yes:
            self.say(f"{prompt} [--yes]")
            return ""
        self.console.write(prompt + " ")
        k = self._first_key()
        while True:
            if k != ESC:
                break
            self.console.write(
                "\n  (Esc aborts a measurement; none is running. Press another key to start, "
                "Ctrl+C to end the session) "
            )
            k = self._wait_key()
        self.console.write("\n")
        return k

    def yes_no(self, prompt: str, default: bool) -> bool:
        """``prompt`` ends with the choices, e.g. "Save <Y> or repeat <N>?"; Y/N keys, Enter
        takes the default (shown in brackets)."""
        shown = f"{prompt} [{'Y' if default else 'N'}]"
        if self.yes:
            self.say(f"{shown} {'Y' if default else 'N'} (--yes)")
            return default
        self.console.write(shown + " ")
        k = self._first_key()
        while True:
            if k in ENTERS:
                answer = default
            elif k.lower() in ("y", "n"):
                answer = k.lower() == "y"
            else:
                shown_key = repr(k) if k.isprintable() else "that key"
                self.console.write(
                    f"\n  {shown_key}: press Y or N (Enter: {'Y' if default else 'N'}) "
                )
                k = self._wait_key()
                continue
            self.console.write(("Y" if answer else "N") + "\n")
            if k not in ENTERS:
                self._answered_by_one_key()
            return answer

    def read_line(self, prompt: str) -> str:
        """A line of text typed by the operator (echoed; Backspace edits; Enter ends)."""
        self.console.write(prompt)
        chars: list[str] = []
        k = self._first_key()
        while k not in ENTERS:
            if k in BACKSPACES:
                if chars:
                    chars.pop()
                    self.console.write("\b \b")
            elif len(k) == 1 and k.isprintable():
                chars.append(k)
                self.console.write(k)
            k = self._wait_key()
        self.console.write("\n")
        return "".join(chars).strip()

    def ask(
        self,
        prompt: str,
        parse: Callable[[str], T],
        default: str | None = None,
        option: str | None = None,
    ) -> T:
        """Ask until ``parse(text)`` accepts the answer (ValueError: its message is shown and
        the question repeated). Empty answer -> ``default`` if given. In --yes mode the default
        is used; none -> UserError asking for ``option``."""
        shown = f"{prompt} [{default}]: " if default is not None else f"{prompt}: "
        if self.yes:
            if default is None:
                raise UserError(f"--yes needs {option or 'an answer'} ({prompt.lower()})")
            self.say(f"{shown}{default} (--yes)")
            return parse(default)
        while True:
            text = self.read_line(shown)
            if not text and default is not None:
                text = default
            try:
                return parse(text)
            except ValueError as exc:
                self.say(f"  {exc}")

    def countdown(self, seconds: float, label: str, any_key: bool = True) -> str | None:
        """Wait ``seconds`` with a live countdown. ``any_key``: any key ends it early (the
        key is returned); otherwise only Esc does (looked for without waiting, so other keys
        stay for the next question). Returns None when the time is up."""
        end = time.monotonic() + seconds
        last_shown = -1
        while True:
            left = end - time.monotonic()
            if left <= 0:
                self.end_progress()
                return None
            whole = int(left + 0.999)
            if whole != last_shown:
                last_shown = whole
                m, s = divmod(whole, 60)
                self.progress(f"{label} {m}:{s:02d}")
            self.idle()
            wait = min(self.poll_s, max(0.0, left))
            if self.yes or not self.console.interactive:
                time.sleep(wait)
                continue
            if not any_key:
                if self.escape_pressed():
                    self.end_progress()
                    return ESC
                time.sleep(wait)
                continue
            k = self.console.key(wait)
            if k is not None:
                self.end_progress()
                return k
