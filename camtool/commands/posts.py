"""``camtool posts``: the registered post-processors, and the plugins that failed or clashed."""
import click

from ..console import echo_json


@click.command("posts")
@click.option("--json", "as_json", is_flag=True, help="Print JSON for scripts.")
def command(as_json: bool) -> None:
    """List the post-processors: name, file extension, the package that provides it, and
    its profile options (type, default, meaning); then every plugin that failed to load
    and every entry point refused because its name clashes (built-ins always win).

    Plugins register in the entry-point group camtool.postprocessors (docs/plugins.md);
    `camtool --no-plugins` and CAMTOOL_PLUGINS=name,... restrict them. Exit 2 when a
    name clashes (a misconfigured cell), after the listing.
    """
    from ..program.registry import describe_plugins

    plugins = describe_plugins()
    clash = any(p.get("clash") for p in plugins)
    if as_json:
        echo_json(plugins)
    else:
        for p in plugins:
            if p.get("clash"):
                click.echo(f"ERROR {p['name']} ({p['entry_point']}): {p['error']}")
                continue
            if p.get("error"):
                click.echo(f"{p['name']:<8} (from {p['source']}) FAILED TO LOAD: {p['error']}")
                continue
            click.echo(f"{p['name']:<8} {p['extension']:<6} from {p['source']} ({p['entry_point']})")
            for k, o in p["options"].items():
                click.echo(f"    {k:<18} {o['type']:<6} default {o['default']!r:<20} {o['doc']}")
    if clash:
        click.get_current_context().exit(2)
