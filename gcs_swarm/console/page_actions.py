"""The live page's operator actions (`--web-token`, gcs_swarm.web.live) carried out as if typed at the
console: the same parser and vocabulary (commands.parse), the same confirmation rule as a script (a verb that
arms or launches needs --yes), the same FlightSession.submit and handlers, so the same refusals."""

from __future__ import annotations

from gcs_swarm.console.commands import CommandError, parse, vocabulary_for
from gcs_swarm.console.session import FlightSession
from gcs_swarm.mission import Mission

WAIT_S = 60.0  # s the flight thread may take to run one action (a hang guard: mode changes retry)


class ConsoleOperator:
    """web.live.Operator over a console's FlightSession."""

    def __init__(self, session: FlightSession, mission: Mission, yes: bool) -> None:
        self.session = session
        self.mission = mission
        self.yes = yes

    def act(self, line: str) -> tuple[bool, list[str]]:
        """Run `line` as the console would; (obeyed, the console's lines about it: its replies and
        refusals, "source: text")."""
        try:
            request = parse(line, vocabulary_for(self.mission, self.session.snapshot()))
        except CommandError as exc:
            return False, [str(exc)]
        if request is None:
            return False, ["an empty command"]
        if request.needs_confirmation and not self.yes:
            return False, [
                f"{request.verb} arms or launches vehicles: run the console with --yes to allow it"
            ]
        before = self.session.events_after(0)
        seq = before[-1].seq if before else 0
        ticket = self.session.submit(request)
        if not ticket.wait(WAIT_S):
            return False, [f"{line}: still running after {WAIT_S:g} s (the console's log will say)"]
        said = [f"{e.source}: {e.text}" for e in self.session.events_after(seq)]
        return ticket.ok, said
