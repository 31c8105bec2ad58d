"""The site's own Sphinx directives: pages generated from the code, so they cannot drift from it.

    ```{cli-help}
    ```                      every subcommand's --help, from toolkit.cli.build_parser
    ```{technique-options} pt_compact_regen
    ```                      a technique's options: its keyword arguments and their defaults
    ```{gpu-prediction} GPUCHECK_JSON METER_JSON CPU_METER_JSON
    ```                      the model of a GPU's wall time (toolkit/measure/gpu_model.py), from reports
    ```{gpu-model-check} GPUCHECK_JSON RENDERS_JSON
    ```                      the same model against what that GPU measured

It also points the two links of the tutorials that leave the tutorials folder (to the README
and scenes/FORMAT.md, which Jupyter opens as files) at the site's pages.
"""
import argparse
import json
import os
from pathlib import Path

from docutils import nodes
from docutils.parsers.rst import Directive
from docutils.statemachine import StringList

# Links a notebook makes out of tutorials/, as Jupyter sees them, and the page the site has instead.
OUTSIDE_LINKS = {"](../README.md)": "](../cli.md)", "](../scenes/FORMAT.md)": "](../scene_format.md)"}
ROOT = Path(__file__).resolve().parents[2]   # the checkout: report paths are relative to it
HELP_WIDTH = "96"   # columns of the help text: argparse reads COLUMNS; fixed, so the page is the same everywhere


def help_block(text):
    """A literal block shown as plain text (not guessed to be Python and coloured)."""
    block = nodes.literal_block(text=text)
    block["language"] = "text"
    return block


def subcommands(parser):
    """(name, subparser) for each command of `python -m toolkit`, in the registry's order."""
    actions = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return list(actions[0].choices.items())


class CliHelp(Directive):
    """The top-level --help, then one section per command with its --help."""

    def run(self):
        from toolkit.cli import build_parser
        os.environ["COLUMNS"] = HELP_WIDTH
        parser = build_parser()
        result = [help_block(parser.format_help())]
        for name, sub in subcommands(parser):
            section = nodes.section(ids=[f"command-{name}"], names=[f"command-{name}"])
            section += nodes.title(text=f"python -m toolkit {name}")
            section += help_block(sub.format_help())
            result.append(section)
        return result


class TechniqueOptions(Directive):
    """A table of the options `toolkit.render(..., options={...})` passes to the technique: the
    same list that render checks options against (toolkit.api.technique_options)."""
    required_arguments = 1

    def run(self):
        from toolkit.api import technique_options
        from toolkit.techniques import TECHNIQUES
        options = technique_options(TECHNIQUES[self.arguments[0]])
        lines = ["| option | default | taken by |", "| --- | --- | --- |"]
        lines += [f"| `{name}` | `{default!r}` | `{owner}` |" for name, (default, owner) in options.items()]
        container = nodes.container()
        self.state.nested_parse(StringList(lines), self.content_offset, container)
        return container.children


class GpuPrediction(Directive):
    """The model's prediction for a GPU, as gpu_model.format_prediction writes it, from a gpucheck
    report of that GPU and the host meter's reports at the GPU's and at the CPU's sizes."""
    required_arguments = 3

    def run(self):
        from toolkit.measure import gpu_model
        gpucheck, meter, cpu_meter = (json.loads((ROOT / path).read_text()) for path in self.arguments)
        return markdown(self, gpu_model.format_prediction(gpu_model.predict(meter, gpucheck, cpu_meter)))


class GpuModelCheck(Directive):
    """The model against the GPU's measured wall time (gpu_model.against_measured): a gpucheck report
    and the meter's renders of the code that GPU ran, at its bench's settings."""
    required_arguments = 2

    def run(self):
        from toolkit.measure import gpu_model
        gpucheck, renders = (json.loads((ROOT / path).read_text()) for path in self.arguments)
        checked = gpu_model.against_measured(renders["techniques"], gpucheck)
        return markdown(self, gpu_model.format_validation(checked))


def markdown(directive, text):
    """`text` (Markdown) parsed into the page where `directive` stands."""
    container = nodes.container()
    directive.state.nested_parse(StringList(text.splitlines()), directive.content_offset, container)
    return container.children


def point_links_at_site(app, docname, source):
    if docname.startswith("tutorials/"):
        for outside, inside in OUTSIDE_LINKS.items():
            source[0] = source[0].replace(outside, inside)


def setup(app):
    app.add_directive("cli-help", CliHelp)
    app.add_directive("technique-options", TechniqueOptions)
    app.add_directive("gpu-prediction", GpuPrediction)
    app.add_directive("gpu-model-check", GpuModelCheck)
    app.connect("source-read", point_links_at_site)
    return {"parallel_read_safe": True}
