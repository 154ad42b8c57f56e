"""``camtool posts``: the installed post-processor plugins."""
import click

from ..console import echo_json


@click.command("posts")
@click.option("--json", "as_json", is_flag=True, help="Print JSON for scripts.")
def command(as_json: bool) -> None:
    """List the installed post-processors: name, file extension, the package that
    provides it, and its profile options (type, default, meaning).

    Plugins register in the entry-point group camtool.postprocessors
    (docs/plugins.md).
    """
    from postprocessors.base import describe_plugins

    plugins = describe_plugins()
    if as_json:
        echo_json(plugins)
        return
    for p in plugins:
        if p.get("error"):
            click.echo(f"{p['name']:<8} (from {p['source']}) FAILED TO LOAD: {p['error']}")
            continue
        click.echo(f"{p['name']:<8} {p['extension']:<6} from {p['source']} ({p['entry_point']})")
        for k, o in p["options"].items():
            click.echo(f"    {k:<18} {o['type']:<6} default {o['default']!r:<20} {o['doc']}")
