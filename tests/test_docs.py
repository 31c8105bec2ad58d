"""The documentation site, tested as a reader reads it: built with the README's command (warnings
are errors), every internal link and image found, every public name documented, and the pages
opened in a headless browser where one is installed.

The build executes the tutorials (docs/conf.py, myst-nb, fast mode) and fails when a cell fails:
it is the suite's notebook test, so the notebooks run once (tests/test_notebooks.py runs them
itself only where Sphinx is missing).
"""
import html
import importlib
import inspect
import os
import re
import shutil
import subprocess
import sys
import threading
from functools import partial
from html.parser import HTMLParser
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
BUILD = DOCS / "_build"
HTML = BUILD / "html"
NOTEBOOKS = sorted((ROOT / "tutorials").glob("*.ipynb"))
SCREENSHOT = BUILD / "tutorial_02.png"
BROWSER = next((shutil.which(name) for name in ("chromium", "chromium-browser", "google-chrome")
                if shutil.which(name)), None)


@pytest.fixture(scope="module")
def site():
    """docs/_build/html, built from scratch (-E: every page read again, every notebook executed)."""
    for package in ("sphinx", "myst_nb", "furo"):
        pytest.importorskip(package, reason=f"{package} is not installed: pip install '.[docs]'")
    env = dict(os.environ, TOOLKIT_DOCS_EXECUTION="force", TOOLKIT_FAST_NOTEBOOKS="1")
    build = subprocess.run([sys.executable, "-m", "sphinx", "-W", "-E", "-q", "-b", "html", str(DOCS), str(HTML)],
                           cwd=ROOT, env=env, capture_output=True, text=True)
    if build.returncode != 0:
        output = build.stdout + build.stderr
        log = "\n".join(output.splitlines()[-80:])
        pytest.fail(f"the site's build failed (a warning, or a tutorial's cell):\n{log}{failed_cell(output)}",
                    pytrace=False)
    return HTML


def failed_cell(output):
    """The failing cell's own error, which Sphinx keeps only in the traceback file it names."""
    saved = re.search(r"The full traceback has been saved in:\s*(\S+)", output)
    if not saved or not Path(saved.group(1)).is_file():
        return ""
    text = re.sub(r"\x1b\[[0-9;]*m", "", Path(saved.group(1)).read_text(errors="replace"))   # no colour codes
    # nbclient's error names the cell's source and its exception; it comes before the chained ExecutionError.
    cause = text.split("The above exception was the direct cause")[0].splitlines()
    return "\n\nthe cell's error, from " + saved.group(1) + ":\n" + "\n".join(cause[-60:])


class Page(HTMLParser):
    """A built page's links, image sources and element ids."""

    def __init__(self, text):
        super().__init__()
        self.links, self.images, self.scripts, self.ids = [], [], [], set()
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if "id" in attrs:
            self.ids.add(attrs["id"])
        if tag == "a" and attrs.get("href"):
            self.links.append(attrs["href"])
        if tag == "img" and attrs.get("src"):
            self.images.append(attrs["src"])
        if tag == "script" and attrs.get("src"):
            self.scripts.append(attrs["src"])
        if tag == "link" and attrs.get("href"):
            self.links.append(attrs["href"])


def pages(html):
    return {path: Page(path.read_text(encoding="utf-8")) for path in sorted(html.rglob("*.html"))}


def test_every_internal_link_and_image_resolves(site):
    parsed = pages(site)
    assert len(parsed) > 25, sorted(p.name for p in parsed)
    broken = []
    for path, page in parsed.items():
        for ref in page.links + page.images + page.scripts:
            url = urlsplit(ref)
            if url.scheme or url.netloc or ref.startswith(("mailto:", "javascript:")):
                continue                                   # outside the site
            target = (path.parent / unquote(url.path)).resolve() if url.path else path
            if not target.is_file():
                broken.append(f"{path.relative_to(site)}: {ref} (no file)")
            elif url.fragment and target.suffix == ".html" and target in parsed \
                    and unquote(url.fragment) not in parsed[target].ids:
                broken.append(f"{path.relative_to(site)}: {ref} (no such anchor)")
    assert not broken, "\n".join(broken)


@pytest.mark.parametrize("notebook", NOTEBOOKS, ids=lambda p: p.name)
def test_tutorial_page_shows_its_outputs(site, notebook):
    """The build ran the notebook (its asserts passed, or the build failed) and its page shows
    the outputs: printed figures, and every figure of the notebook as an image that exists."""
    page = site / "tutorials" / f"{notebook.stem}.html"
    text = page.read_text(encoding="utf-8")
    assert 'class="output' in text, f"{page.name}: no cell outputs: the notebook was not executed"
    images = Page(text).images
    plots = notebook.read_text(encoding="utf-8").count("plt.show()") + \
        notebook.read_text(encoding="utf-8").count("display(Image(")
    assert len(images) >= plots, f"{page.name}: {len(images)} images for {plots} figures"
    for src in images:
        data = (page.parent / unquote(src)).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 2000, f"{page.name}: {src} is not a figure"


def documented_modules():
    """The modules the API page documents (its automodule lines)."""
    return re.findall(r"\.\. automodule:: ([\w.]+)", (DOCS / "api.md").read_text(encoding="utf-8"))


def shown_docstring(api_html, full_name):
    """The text the API page shows under `full_name`'s signature, or None."""
    match = re.search(rf'id="{re.escape(full_name)}".*?</dt>\s*<dd>(.*?)</dd>', api_html, re.S)
    return None if match is None else re.sub(r"<[^>]+>", "", match.group(1)).strip()


def test_every_public_name_has_a_docstring_on_the_api_page(site):
    modules = documented_modules()
    assert "toolkit" in modules and "toolkit.techniques" in modules, modules
    api = (site / "api.html").read_text(encoding="utf-8")
    missing = []
    for module_name in modules:
        module = importlib.import_module(module_name)
        for name in module.__all__:
            value = getattr(module, name)
            if not (inspect.isfunction(value) or inspect.isclass(value)):
                continue                                   # a constant: no docstring of its own
            if not inspect.getdoc(value) or not shown_docstring(api, f"{module_name}.{name}"):
                missing.append(f"{module_name}.{name}")
    assert not missing, f"public names without a docstring on the API page: {missing}"


def test_command_line_page_has_every_command_and_option(site):
    from toolkit.cli import build_parser
    sys.path.insert(0, str(DOCS / "_ext"))
    from toolkit_docs import subcommands
    text = (site / "cli.html").read_text(encoding="utf-8")
    for name, sub in subcommands(build_parser()):
        assert f"python -m toolkit {name}" in text, name
        options = [s for action in sub._actions for s in action.option_strings if s.startswith("--")]
        absent = [o for o in options if o not in text]
        assert not absent, f"cli page, {name}: {absent}"


def page_text(path):
    """A page as a reader sees its text: tags dropped, entities decoded."""
    return html.unescape(re.sub(r"<[^>]+>", "", path.read_text(encoding="utf-8")))


def test_technique_pages_show_their_real_files(site):
    """Each technique's page shows every line of its kernel and its host module, as they are now,
    and the options that toolkit.render accepts for it."""
    from toolkit.api import technique_options
    from toolkit.techniques import TECHNIQUES
    for name in TECHNIQUES:
        page = site / "techniques" / f"{name}.html"
        table = re.search(r"<table.*?</table>", page.read_text(encoding="utf-8"), re.S).group(0)
        first_cells = re.findall(r"<tr[^>]*>\s*<td[^>]*>(.*?)</td>", table, re.S)
        options = [re.sub(r"<[^>]+>", "", cell).strip() for cell in first_cells]
        assert options == list(technique_options(TECHNIQUES[name])), f"{page.name}: options table {options}"
        text = page_text(page)
        for source in (ROOT / "cl" / f"{name}.cl", ROOT / "toolkit" / "techniques" / f"{name}.py"):
            absent = [line for line in source.read_text(encoding="utf-8").splitlines()
                      if line.strip() and line.strip() not in text]
            assert not absent, f"techniques/{name}.html does not show {source.name}: {absent[:3]}"


def browse(*args):
    """Headless chromium on the built site; returns its stdout and stderr."""
    run = subprocess.run([BROWSER, "--headless", "--no-sandbox", "--disable-gpu", "--enable-logging=stderr",
                          "--virtual-time-budget=8000", *args], capture_output=True, text=True, timeout=120)
    return run.stdout, run.stderr


class QuietHandler(SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass


@pytest.fixture
def served(site):
    """The site over HTTP on a free local port, as a reader's browser gets it (the search
    fetches pages, which a browser refuses from file:// URLs)."""
    server = ThreadingHTTPServer(("127.0.0.1", 0), partial(QuietHandler, directory=str(site)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


def console_errors(log):
    return [line for line in log.splitlines() if "CONSOLE" in line and re.search(r"error|uncaught", line, re.I)]


@pytest.mark.skipif(BROWSER is None, reason="no headless browser (chromium) installed: apt-get install chromium")
def test_pages_in_a_browser(served):
    """Tutorial 2 shows its efficiency plot (saved as docs/_build/tutorial_02.png), a technique
    page shows its code, the search finds pt_compact_regen, and no page logs a console error."""
    tutorial = f"{served}/tutorials/02_regeneration_and_compaction.html"
    dom, log = browse("--dump-dom", tutorial)
    assert dom.count("<img") >= 2, "tutorial 2 shows no figures in the browser"
    errors = console_errors(log)
    SCREENSHOT.unlink(missing_ok=True)
    # Tall enough to reach section 2's efficiency plot (a browser's screenshot ignores #anchors).
    _, log = browse(f"--screenshot={SCREENSHOT}", "--hide-scrollbars", "--window-size=1280,7000", tutorial)
    assert SCREENSHOT.is_file() and SCREENSHOT.stat().st_size > 10_000, "no screenshot"
    errors += console_errors(log)
    dom, log = browse("--dump-dom", f"{served}/techniques/pt_compact_regen.html")
    assert 'class="highlight-c' in dom and "__kernel" in re.sub(r"<[^>]+>", "", dom), "no kernel code shown"
    errors += console_errors(log)
    dom, log = browse("--dump-dom", f"{served}/search.html?q=pt_compact_regen")
    found = re.findall(r'<a href="([^"]+)"', dom[dom.find('id="search-results"'):])
    assert any("techniques/pt_compact_regen.html" in href for href in found), found[:10]
    errors += console_errors(log)
    assert not errors, errors


# Imports the tutorials reach that belong to another extra on purpose, each behind its own option
# (none of the tutorials' cells takes it): Dask for `study --scheduler`, Mitsuba for `bench --peer`.
OTHER_EXTRAS = {"distributed": "cluster", "mitsuba": "peers"}


def _requirements(section, key):
    """The distribution names one setup.cfg list names (comments and markers left out)."""
    import configparser
    from packaging.requirements import Requirement
    config = configparser.ConfigParser()
    config.read(ROOT / "setup.cfg")
    lines = [line.split("#")[0].strip() for line in config[section][key].splitlines()]
    return {Requirement(line).name.lower().replace("_", "-") for line in lines if line}


def _with_dependencies(names):
    """`names` and every distribution they require, as installed here (markers evaluated, extras not)."""
    from importlib import metadata
    from packaging.requirements import Requirement
    found, todo = set(), list(names)
    while todo:
        name = todo.pop()
        if name in found:
            continue
        found.add(name)
        try:
            requires = metadata.requires(name) or []
        except metadata.PackageNotFoundError:
            continue
        for text in requires:
            requirement = Requirement(text)
            if requirement.marker is None or requirement.marker.evaluate({"extra": ""}):
                todo.append(requirement.name.lower().replace("_", "-"))
    return found


def _imports(source):
    """The modules a piece of Python imports (absolute imports, wherever they stand)."""
    import ast
    tree = ast.parse("\n".join(line for line in source.splitlines() if not line.lstrip().startswith(("%", "!"))))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            yield node.module
            yield from (f"{node.module}.{alias.name}" for alias in node.names)


def test_the_docs_extra_carries_what_the_tutorials_import():
    """`pip install ".[docs]"` then the README's build command executes every tutorial: every module
    they import, and every module of the toolkit they import imports in turn (at its top or inside a
    function), must come with Python, the toolkit's requirements or the docs extra. (The build failed
    on a fresh environment at tutorial 01's live view: Panel was only in the test extra.)"""
    import json
    from importlib import metadata
    allowed = _with_dependencies(_requirements("options", "install_requires") | _requirements("options.extras_require", "docs"))
    distributions = {module: {d.lower().replace("_", "-") for d in dists}
                     for module, dists in metadata.packages_distributions().items()}
    seen, todo, third_party = set(), [], {}
    for notebook in NOTEBOOKS:
        cells = json.loads(notebook.read_text())["cells"]
        todo += [(name, notebook.name) for cell in cells if cell["cell_type"] == "code"
                 for name in _imports("".join(cell["source"]))]
    while todo:
        name, where = todo.pop()
        top = name.split(".")[0]
        if name in seen or top in sys.stdlib_module_names or top in OTHER_EXTRAS:
            continue
        seen.add(name)
        if top != "toolkit":
            third_party.setdefault(top, where)
            continue
        path = ROOT.joinpath(*name.split("."))
        for file in (path / "__init__.py", path.with_suffix(".py")):
            if file.is_file():
                todo += [(imported, str(file.relative_to(ROOT))) for imported in _imports(file.read_text())]
    assert {"panel", "numpy", "pyopencl"} <= set(third_party)   # the walk found the toolkit's own imports
    missing = {top: where for top, where in third_party.items() if not distributions.get(top, set()) & allowed}
    assert not missing, f"imported by the tutorials (module: where) but not in the docs extra: {missing}"
