"""`gcs-swarm console`: watch and command a flying swarm from the terminal (docs/console.md).

A thin layer over the `run` command's objects: `session.FlightSession` is the flight thread that owns the
Fleet and the MissionRunner; `commands` parses the command language; `snapshot` and `view` compute and render
what is shown; `app` is the full-screen prompt_toolkit UI, `script` the plain line mode; `main` wires it up.
"""
