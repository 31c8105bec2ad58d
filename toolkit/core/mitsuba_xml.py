"""Reading Mitsuba 3's XML into a tree of `Node`s, each knowing its file and line (scenes/FORMAT.md,
"Mitsuba 3 XML"). What the elements mean is mitsuba_scene.py's; this file only reads.

A scene file is untrusted input. defusedxml's SAX parser reads it: a document that defines
entities (the "billion laughs" bomb nests them to expand without bound) or names external ones
is refused before anything expands. Every file is a regular file inside the scene's folder; the
XML read for one scene (includes counted each time) is at most LIMITS["scene.xml.bytes"], its
elements nest at most LIMITS["scene.xml.depth"] deep and its includes at most
LIMITS["scene.xml.includes"]. An `include` of a file that is already being read (a cycle) is an
error naming the chain. Each problem is an InputError naming the file and line.

`include` is replaced by the included file's children; `default` sets a parameter unless it is
already set, and `$name` in an attribute is replaced by the parameter's value, as Mitsuba does.
"""
import re
import xml.sax
from dataclasses import dataclass, field
from pathlib import Path

import defusedxml.sax
from defusedxml import DefusedXmlException

from toolkit.core.errors import InputError
from toolkit.core.validate import LIMITS, in_range, regular_file_inside

PARAMETER = re.compile(r"\$([A-Za-z_][A-Za-z0-9_]*)")


@dataclass
class Node:
    tag: str
    attrib: dict
    where: str                      # "file:line", for every message about this element
    children: list = field(default_factory=list)

    def describe(self):
        kind = self.attrib.get("type") or self.attrib.get("name")
        return f"<{self.tag}{' ' + repr(kind) if kind else ''}>"


class _TreeBuilder(xml.sax.ContentHandler):
    """Nodes from SAX events, the line of each start tag kept; the nesting depth limited."""

    def __init__(self, path):
        super().__init__()
        self.path, self.stack, self.root, self.locator = path, [], None, None

    def setDocumentLocator(self, locator):
        self.locator = locator

    def startElement(self, name, attrs):
        where = f"{self.path}:{self.locator.getLineNumber()}"
        in_range("scene.xml.depth", len(self.stack) + 1, f"{where}: element nesting depth")
        node = Node(name, dict(attrs), where)
        if self.stack:
            self.stack[-1].children.append(node)
        else:
            self.root = node
        self.stack.append(node)

    def endElement(self, name):
        self.stack.pop()


class XmlReader:
    """Reads one scene: its main file and what it includes, with one budget of bytes."""

    def __init__(self, main):
        self.main = Path(main)
        self.folder = self.main.parent          # Mitsuba resolves every relative filename from here
        self.bytes_read = self.files_read = 0
        self.parameters = {}

    def read(self):
        """The main file's root <scene> with its includes expanded and parameters substituted."""
        root = self._parse(self.main, ())
        if root.tag != "scene":
            raise InputError(f"{root.where}: the root element must be <scene>, got <{root.tag}>")
        return root

    def resolve(self, node, filename, what, size_limit):
        """A filename an element names, relative to the main file's folder and inside it."""
        if not filename:
            raise InputError(f"{node.where}: {node.describe()} names no filename")
        try:
            return regular_file_inside(self.folder / filename, self.folder, what, size_limit)
        except InputError as error:
            raise InputError(f"{node.where}: {error}") from None

    def _parse(self, path, chain):
        data = path.read_bytes()
        self.bytes_read += len(data)
        in_range("scene.xml.bytes", self.bytes_read, f"{path}: XML read for this scene (bytes, includes counted)")
        self.files_read += 1
        in_range("scene.xml.files", self.files_read, f"{path}: XML files parsed for this scene (includes counted)")
        builder = _TreeBuilder(path)
        try:
            defusedxml.sax.parseString(data, builder)
        except xml.sax.SAXParseException as error:
            raise InputError(f"{path}:{error.getLineNumber()}: malformed XML: {error.getMessage()}") from None
        except DefusedXmlException as error:
            raise InputError(f"{path}: refused XML: {error} (entity and DTD definitions are not read: they "
                             "can expand without bound)") from None
        if builder.root is None:
            raise InputError(f"{path}: no XML element")
        return self._expand(builder.root, (*chain, path))

    def _expand(self, node, chain):
        """`node` with parameters substituted, defaults set and includes replaced, in document order."""
        node.attrib = {k: self._substitute(node, v) for k, v in node.attrib.items()}
        children = []
        for child in node.children:
            if child.tag == "default":
                name, value = child.attrib.get("name"), child.attrib.get("value")
                if name is None or value is None:
                    raise InputError(f"{child.where}: <default> needs a name and a value")
                self.parameters.setdefault(name, value)
            elif child.tag == "include":
                children.extend(self._include(self._expand(child, chain), chain))
            else:
                children.append(self._expand(child, chain))
        node.children = children
        return node

    def _include(self, node, chain):
        path = self.resolve(node, node.attrib.get("filename"), "included file", "scene.xml.bytes")
        if path in chain:
            raise InputError(f"{node.where}: include cycle: " + " includes ".join(p.name for p in (*chain, path)))
        in_range("scene.xml.includes", len(chain), f"{node.where}: include nesting depth")
        root = self._parse(path, chain)
        if root.tag != "scene":
            raise InputError(f"{root.where}: an included file's root element must be <scene>, got <{root.tag}>")
        return root.children

    def _substitute(self, node, value):
        def parameter(match):
            if match.group(1) not in self.parameters:
                raise InputError(f"{node.where}: ${match.group(1)} has no value (no <default name="
                                 f"\"{match.group(1)}\"> before it)")
            return self.parameters[match.group(1)]
        return PARAMETER.sub(parameter, value)


def read_xml(path):
    """(the expanded root Node of the scene file `path`, its XmlReader for resolving filenames)."""
    reader = XmlReader(regular_file_inside(path, Path(path).parent, "scene file", "scene.xml.bytes"))
    return reader.read(), reader
