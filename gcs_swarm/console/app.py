"""The interactive console: a full-screen prompt_toolkit application over a FlightSession.

Screen, top to bottom: title; fleet table and mission line (re-rendered 4 times a second from the latest
snapshot); event log (replies, refusals with their reason, STATUSTEXT, phase changes, lost/regained links);
key hints; the command line (history in the run folder, Tab completion of commands, vehicle names, modes,
parameter names, shapes). Commands that arm or launch ask first unless --yes; `quit` (or Ctrl-D) while
vehicles are airborne offers to land them first. This module only renders and routes commands.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

from prompt_toolkit.application import Application
from prompt_toolkit.completion import CompleteEvent, Completer, Completion
from prompt_toolkit.data_structures import Point
from prompt_toolkit.document import Document
from prompt_toolkit.filters import has_completions
from prompt_toolkit.formatted_text import StyleAndTextTuples
from prompt_toolkit.history import FileHistory
from prompt_toolkit.key_binding import KeyBindings, KeyPressEvent
from prompt_toolkit.layout import ConditionalContainer, Float, FloatContainer, HSplit, Layout, Window
from prompt_toolkit.layout.controls import FormattedTextControl
from prompt_toolkit.layout.menus import CompletionsMenu
from prompt_toolkit.styles import Style
from prompt_toolkit.widgets import TextArea

from gcs_swarm.console.commands import CommandError, Request, complete, help_lines, parse, vocabulary_for
from gcs_swarm.console.session import FlightSession
from gcs_swarm.console.view import Line, event_line, fleet_table, mission_line, status_lines
from gcs_swarm.flight.phase import Phase
from gcs_swarm.mission import Mission

EXIT_OK, EXIT_USER_ERROR = 0, 2
LOG_LINES = 500
HINT = "Tab completes  Up/Down history  help lists commands  Ctrl-C clears the line  Ctrl-D quits"

STYLE = Style.from_dict(
    {
        "title": "reverse bold",
        "header": "bold underline",
        "phase": "bold ansicyan",
        "stale": "ansiyellow",
        "warning": "ansiyellow bold",
        "error": "ansired bold",
        "emergency": "bg:ansired ansiwhite bold",
        "crashed": "bg:ansired ansiwhite bold",
        "failsafe": "bg:ansimagenta ansiwhite bold",
        "command": "bold",
        "time": "ansibrightblack",
        "hint": "ansibrightblack",
        "prompt": "bold ansigreen",
        "question": "bold ansiyellow",
    }
)


@dataclass(frozen=True)
class _Question:
    """A pending yes/no or multiple-choice question: the answer's first letter picks the action."""

    text: str
    answers: dict[str, Callable[[], None]]
    default: str


class ConsoleApp:
    """The full-screen console; `run()` returns the exit status."""

    def __init__(
        self, session: FlightSession, mission: Mission, title: str, history: Path, yes: bool = False
    ) -> None:
        self.session = session
        self.mission = mission
        self.title = title
        self.yes = yes
        self.log: deque[Line] = deque(maxlen=LOG_LINES)
        self.status = EXIT_OK
        self._seq = 0
        self._question: _Question | None = None
        self._landing_to_quit = False
        self.input = TextArea(
            height=1,
            prompt=self._prompt,
            multiline=False,
            history=FileHistory(str(history)),
            completer=_CommandCompleter(self),
            accept_handler=self._accept,
            complete_while_typing=False,
        )
        n = len(mission.vehicles)
        body = HSplit(
            [
                Window(FormattedTextControl(lambda: [("class:title", self.title)]), height=1),
                Window(FormattedTextControl(self._table), height=n + 1),
                Window(FormattedTextControl(self._mission), height=1),
                Window(char="-", height=1, style="class:hint"),
                Window(
                    FormattedTextControl(self._log_text, get_cursor_position=self._log_end),
                    wrap_lines=False,
                ),
                Window(FormattedTextControl([("class:hint", HINT)]), height=1),
                self.input,
            ]
        )
        layout = FloatContainer(
            body,
            floats=[
                Float(
                    xcursor=True,
                    ycursor=True,
                    content=ConditionalContainer(CompletionsMenu(max_height=8), filter=has_completions),
                )
            ],
        )
        self.app: Application[None] = Application(
            layout=Layout(layout, focused_element=self.input),
            key_bindings=self._keys(),
            style=STYLE,
            full_screen=True,
            refresh_interval=0.25,
        )
        self.app.before_render += self._before_render

    def run(self) -> int:
        self.app.run()
        snapshot = self.session.snapshot()
        if snapshot.state == "failed":
            print(f"error: {snapshot.error}")
            return EXIT_USER_ERROR
        return self.status

    # ------------------------------------------------------------------ rendering

    def _table(self) -> StyleAndTextTuples:
        return _join(fleet_table(self.session.snapshot()))

    def _mission(self) -> StyleAndTextTuples:
        return list(mission_line(self.session.snapshot()))

    def _log_text(self) -> StyleAndTextTuples:
        return _join(self.log)

    def _log_end(self) -> Point:
        return Point(0, max(len(self.log) - 1, 0))

    def _prompt(self) -> StyleAndTextTuples:
        if self._landing_to_quit:
            return [("class:question", "landing before quitting (Ctrl-C leaves now) > ")]
        if self._question is not None:
            return [("class:question", self._question.text + " ")]
        return [("class:prompt", "swarm> ")]

    def _before_render(self, _app: object) -> None:
        """Pull new events; finish a landing-before-quit; leave when the session failed to connect."""
        for event in self.session.events_after(self._seq):
            self._seq = event.seq
            self.log.append(event_line(event))
        snapshot = self.session.snapshot()
        if self._landing_to_quit and snapshot.settled:
            self._exit()
        if snapshot.state == "failed" and snapshot.mission.phase is Phase.CONNECT:
            self._exit()

    def _exit(self) -> None:
        if self.app.is_running and not self.app.is_done:
            self.app.exit()

    def _say(self, lines: Iterable[str], style: str = "") -> None:
        for text in lines:
            self.log.append([(style, text)])

    # ------------------------------------------------------------------ input

    def _keys(self) -> KeyBindings:
        keys = KeyBindings()

        @keys.add("c-c")
        def _interrupt(event: KeyPressEvent) -> None:
            if self._landing_to_quit:
                self._exit()
            elif self.input.text:
                self.input.text = ""
            elif self._question is not None:
                self._question = None
                self._say(["cancelled"])
            else:
                self._quit()

        @keys.add("c-d")
        def _eof(event: KeyPressEvent) -> None:
            if not self.input.text:
                self._quit()

        return keys

    def _accept(self, buffer: object) -> bool:
        text = self.input.text
        if self._question is not None:
            self._answer(text)
            return False
        if self._landing_to_quit:
            self._say(["landing before quitting: wait, or Ctrl-C to leave now"], "class:warning")
            return False
        snapshot = self.session.snapshot()
        try:
            request = parse(text, vocabulary_for(self.mission, snapshot))
        except CommandError as exc:
            self._say([f"> {text}"], "class:command")
            self._say([f"error: {exc}"], "class:error")
            return False
        if request is None:
            return False
        self._say([f"> {text.strip()}"], "class:command")
        self._run(request)
        return False

    def _run(self, request: Request) -> None:
        if request.verb == "help":
            self._say(help_lines(request.name or None))
        elif request.verb == "status":
            self._say(status_lines(self.session.snapshot()))
        elif request.verb in ("wait", "wait_phase"):
            self._say(["error: wait paces scripts (--script FILE); here, just watch"], "class:error")
        elif request.verb == "quit":
            self._quit()
        elif request.needs_confirmation and not self.yes:
            if request.every or request.verb == "start":
                who = "every vehicle"
            else:
                who = ", ".join(self.mission.vehicles[i].name for i in request.vehicles)
            self._ask(
                f"{request.line}: this arms or launches {who}. Go ahead? [y/N]",
                {"y": lambda: self._submit(request), "n": lambda: self._say(["cancelled"])},
                "n",
            )
        else:
            self._submit(request)

    def _submit(self, request: Request) -> None:
        self.session.submit(request)

    def _ask(self, text: str, answers: dict[str, Callable[[], None]], default: str) -> None:
        self._question = _Question(text, answers, default)

    def _answer(self, text: str) -> None:
        question, self._question = self._question, None
        assert question is not None
        key = (text.strip()[:1] or question.default).lower()
        self._say([f"{question.text} {text.strip()}"], "class:command")
        action = question.answers.get(key)
        if action is None:
            self._say([f"no such answer {text.strip()!r}: cancelled"], "class:warning")
            return
        action()

    def _quit(self) -> None:
        snapshot = self.session.snapshot()
        if snapshot.state != "ready" or snapshot.settled:
            self._exit()
            return
        names = ", ".join(snapshot.airborne or snapshot.armed) or "vehicles"
        self._ask(
            f"{names} still armed or flying: [l]and them first, [q]uit leaving them, [c]ancel?",
            {"l": self._land_then_quit, "q": self._exit, "c": lambda: self._say(["cancelled"])},
            "c",
        )

    def _land_then_quit(self) -> None:
        self._landing_to_quit = True
        self._submit(Request("abort", "abort"))


class _CommandCompleter(Completer):
    """Tab completion from `commands.complete` and the current vocabulary."""

    def __init__(self, console: ConsoleApp) -> None:
        self.console = console

    def get_completions(self, document: Document, complete_event: CompleteEvent) -> Iterable[Completion]:
        text = document.text_before_cursor
        partial = "" if not text or text[-1].isspace() else text.split()[-1]
        vocabulary = vocabulary_for(self.console.mission, self.console.session.snapshot())
        for word in complete(text, vocabulary):
            yield Completion(word, start_position=-len(partial))


def _join(lines: Iterable[Line]) -> StyleAndTextTuples:
    out: StyleAndTextTuples = []
    for k, line in enumerate(lines):
        if k:
            out.append(("", "\n"))
        out.extend(line)
    return out
