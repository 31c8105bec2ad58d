"""What a student's file may include, checked before the compiler sees it.

A submission is built in place of a toolkit file, in a folder of its own (grade.py). Its
`#include "name"` lines are inlined by the toolkit (program.py), never by the compiler, and each
may name, by a plain file name (no folder, no `..`, no absolute path):
  - a file of that folder (the grader's own kernels beside it), or
  - one of the toolkit's cl/ headers that the assignment lists (Assignment.headers),
and never the file it replaces: that is the toolkit's solution. Any other way to reach a file
(`#include <...>`, a macro as the name, a line continuation, `%:include`, `#embed`...) is
refused: the compiler would read whatever it names, another student's file or /proc/self/environ.
"""
import re

from toolkit.grading.stubs import CourseSources
from toolkit.opencl.program import INCLUDE_LINE, MAX_SOURCE_SIZE, KernelBuildError, cl_dir, inlined_include

# A name a student may include: letters, digits, `_`, `-` and dots, not starting with a dot.
_PLAIN_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")
# Directives that read another file (C, clang's extensions, C23's #embed).
_FILE_DIRECTIVES = ("import", "embed")
# The three translation phases before directives are recognised (C99 5.1.1.2): trigraphs (clang
# reads them in OpenCL C), backslash-newline splices (clang allows spaces between), comments.
_TRIGRAPHS = {"=": "#", "/": "\\", "'": "^", "(": "[", ")": "]", "!": "|", "<": "{", ">": "}", "-": "~"}
_SPLICE = re.compile(r"\\[ \t]*$")
_DIRECTIVE = re.compile(r"[ \t\f\v]*(?:#|%:)[ \t\f\v]*([A-Za-z_]\w*)")


def include_problem(name, replaces, headers):
    """Why a student's file may not `#include "name"`, or None. `replaces`: the toolkit file it is
    built in place of; `headers`: the cl/ headers the assignment allows."""
    if name.startswith("/"):
        return f"an absolute path: include a toolkit header by its plain name ({_allowed(headers)})"
    if ".." in name.split("/") or "/" in name or "\\" in name:
        return f"it names a folder: include only plain file names ({_allowed(headers)})"
    if not _PLAIN_NAME.fullmatch(name):
        return f"not a plain file name ({_allowed(headers)})"
    if name == replaces:
        return f"your file replaces {replaces}, the toolkit's solution, and cannot include it"
    return None


def _allowed(headers):
    return "allowed: " + ", ".join(sorted(headers)) if headers else "this assignment allows no toolkit header"


def directives(text):
    """(line, name) of every preprocessing directive in C source `text`, as the compiler sees it:
    after trigraphs, line splices and comments. `line` is the physical line it starts on. Lines
    are split as program.py splits them (str.splitlines): the compiler gets them that way."""
    text = re.sub(r"\?\?([=/'()!<>-])", lambda m: _TRIGRAPHS[m.group(1)], text)
    return list(_directives_of(_without_comments(_spliced(text.splitlines()))))


def _spliced(lines):
    """Logical lines, backslash-newline splices joined: (first physical line, text)."""
    out, first, current = [], 1, []
    for number, line in enumerate(lines, start=1):
        continued = _SPLICE.search(line)
        current.append(line[:continued.start()] if continued else line)
        if not continued:
            out.append((first, "".join(current)))
            first, current = number + 1, []
    if current:
        out.append((first, "".join(current)))
    return out


# A comment, or a string or character literal (kept: a "/*" inside one starts no comment).
_COMMENT_OR_LITERAL = re.compile(r"""//[^\n]*|/\*.*?(?:\*/|\Z)|"(?:\\.|[^"\\\n])*"?|'(?:\\.|[^'\\\n])*'?""", re.S)


def _without_comments(lines):
    """The logical lines with each comment replaced by a space; a block comment keeps its line
    breaks, so that every line stays where it was (and what follows `*/` starts a line)."""
    text = "\n".join(line for _, line in lines)

    def blank(match):
        found = match.group(0)
        return " " + "\n" * found.count("\n") if found.startswith("/") else found
    return zip([first for first, _ in lines], _COMMENT_OR_LITERAL.sub(blank, text).split("\n"))


def _directives_of(lines):
    for first, line in lines:
        match = _DIRECTIVE.match(line)
        if match:
            yield first, match.group(1)


class SubmissionSources(CourseSources):
    """Where a build of a submission finds its files (program.Sources): its folder, then cl/, as for
    any build; but what the student's file (`replaces`, in `folder`) includes must pass the rules
    of this module's docstring, and its text is read as it is checked. The toolkit's own copy of
    `replaces` is refused if it is the stub (stubs.py: CourseSources); other stubs build as they are."""

    def __init__(self, folder, replaces, headers):
        super().__init__(folder, refused={replaces})
        self.replaces, self.headers = replaces, tuple(headers)

    def _is_students(self, path):
        return path is not None and path.name == self.replaces and path.parent.resolve() == self.folder.resolve()

    def find(self, name, includer=None, line=None):
        if not self._is_students(includer):
            return super().find(name, includer, line)   # the toolkit's files and the grader's: trusted
        problem = include_problem(name, self.replaces, self.headers)
        path = None if problem else self._beside(name, line) or (cl_dir() / name if name in self.headers else None)
        if path is None:
            raise self._error(line, f'#include "{name}": {problem or _unknown(self.headers)}')
        return path

    def _beside(self, name, line):
        """folder/name, if it is a file of the folder (not a symbolic link to somewhere else)."""
        path = self.folder / name
        if path.is_symlink() and path.resolve().parent != self.folder.resolve():
            raise self._error(line, f'#include "{name}": a symbolic link to a file outside your folder')
        return path if path.is_file() else None

    def read(self, path):
        if not self._is_students(path):
            return super().read(path)
        if path.stat().st_size > MAX_SOURCE_SIZE:
            raise self._error(1, f"your file has {path.stat().st_size:,} bytes, more than the {MAX_SOURCE_SIZE:,} "
                                 "a build may have")
        data = path.read_bytes()
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError as error:
            raise self._error(data[:error.start].count(b"\n") + 1, "your file is not UTF-8 text") from None
        self._check_includes(text)
        return text

    def _check_includes(self, text):
        """Refuse any directive that reads a file unless it is a line that program.py inlines, and
        any such line that the compiler would not read as a directive (in a comment, or after a
        line continuation): the inlined header's own `*/` would end that comment early."""
        lines = text.splitlines()
        found = directives(text)
        for number, directive in found:
            reads_a_file = "include" in directive or directive in _FILE_DIRECTIVES
            if reads_a_file and not (directive == "include" and INCLUDE_LINE.match(lines[number - 1])):
                raise self._error(number, f'#{directive}: a file may be included only by `#include "name.h"` '
                                          "on a line of its own, with no comment after it")
        real = {number for number, directive in found if directive == "include"}
        hidden = [n for n, line in enumerate(lines, start=1) if inlined_include(line) and n not in real]
        if hidden:
            raise self._error(hidden[0], "an #include inside a comment or after a line continuation: "
                                         "remove it, or put it on a line of its own")

    def _error(self, line, message):
        """A build error at `line` of the student's file (the worker names their file, not ours)."""
        return KernelBuildError(f"{self.replaces}:{line or 1}: error: {message}")


def _unknown(headers):
    return f"neither a file beside yours nor a toolkit header that this assignment allows ({_allowed(headers)})"
