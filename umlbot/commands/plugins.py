"""`umlbot plugins`: what the installed packages add to umlbot (entry points), and what is broken.

Lists each package with its component kinds, service kinds, implementations (with seed aliases)
and drivers, then every plugin that was skipped and why; exit 1 when one was. Reading a driver's
entry point does not import it, so listing is safe on any machine.
"""

from __future__ import annotations

import json
import sys
from dataclasses import asdict

import click


@click.command(name="plugins")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document instead of the list.")
def command(as_json: bool) -> None:
    """List the installed component and driver plugins; exit 1 if one could not be loaded."""
    from umlbot.base.plugins import catalog

    lib = catalog()
    packages = sorted(lib.packages.values(), key=lambda p: (p.package != "umlbot", p.package.lower()))
    if as_json:
        click.echo(json.dumps({"packages": [asdict(p) for p in packages],
                               "problems": [asdict(p) for p in lib.problems]}, indent=2))
    else:
        for package in packages:
            click.echo(f"{package.package} {package.version}")
            for label, names in (("component kinds", package.kinds), ("service kinds", package.services),
                                 ("implementations", package.implementations),
                                 ("drivers", package.drivers)):
                if names:
                    click.echo(f"  {label}: {', '.join(names)}")
        for problem in lib.problems:
            click.echo(f"skipped {problem}", err=True)
    if lib.problems:
        sys.exit(1)
