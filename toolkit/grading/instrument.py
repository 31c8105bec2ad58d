"""Instrumented builds of a student's file: count how often a function's loops go round (is the
scan parallel, is the search logarithmic?) and how many atomics reach the global counter.

A macro cannot hide a loop or an atomic from these counts: the student's file is run through the
C preprocessor first (every macro expanded, `#undef` and `##` included), and the counting is
written into the expanded text, which has no directives left to undo it. Their `#include` lines
(already checked by sources.py) are kept aside and put back in front; their `#define`s go after
the code, for the toolkit files that include theirs (compact.cl uses COMPACT_SCRATCH_INTS).
The preprocessor runs with no include path and no system macros, under a time and size limit.
"""
import re
import shutil
import subprocess
from functools import lru_cache

from toolkit.grading.assignment import CheckFailed, CheckSkipped
from toolkit.opencl.program import INCLUDE_LINE, MAX_SOURCE_SIZE, define_options

COUNTER = "grade_iterations"    # the private int* that the counted copy of a function ticks
_TICK = f"(++*{COUNTER} > 0)"   # true, and one more round
_TOKEN = re.compile(r""""(?:\\.|[^"\\\n])*"|'(?:\\.|[^'\\\n])*'|[A-Za-z_]\w*|\d[\w.]*|\s+|.""")
_LOOPS = {"for", "while", "do", "goto"}
# Every atomic read-modify-write form: OpenCL 1.x (atomic_*, atom_*), OpenCL 2.0 / C11
# (atomic_fetch_*, atomic_exchange*, atomic_compare_exchange_*), and clang's builtins.
_ATOMIC = re.compile(r"(atomic|atom)_(add|sub|inc|dec|xchg|cmpxchg|min|max|and|or|xor)"
                     r"|atomic_(fetch_\w+|exchange\w*|compare_exchange_\w+|flag_test_and_set\w*)"
                     r"|__(sync|atomic|c11_atomic|opencl_atomic|hip_atomic)_\w+")
_NOT_RMW = re.compile(r"fence|synchronize|load|store|init|lock_free")


_CPP_OPTIONS = ["-P", "-dD", "-undef", "-nostdinc", "-w", "-x", "c", "-std=c11"]


@lru_cache(maxsize=None)
def _predefined(cpp):
    """Names that `cpp` defines by itself even with -undef (__STDC__, __STDC_VERSION__, ...): the
    OpenCL compiler defines its own, and a second #define of them is an error there."""
    run = subprocess.run([cpp, *_CPP_OPTIONS, "-"], input="", capture_output=True, text=True, timeout=20)
    return frozenset(re.findall(r"^\s*#\s*define\s+(\w+)", run.stdout, re.M))


def preprocessed(text, defines):
    """(include lines, expanded code, #define lines) of the student's file `text` built with `defines`."""
    lines = text.splitlines()
    includes = [line for line in lines if INCLUDE_LINE.match(line)]
    kept = "\n".join("" if INCLUDE_LINE.match(line) else line for line in lines)
    cpp = shutil.which("cpp")
    if cpp is None:
        raise CheckSkipped("this check needs a C preprocessor (cpp, from gcc or clang), which is not installed")
    options = [o for o in define_options(defines or {}) if o.startswith("-D")]
    try:
        run = subprocess.run([cpp, *_CPP_OPTIONS, *options, "-"],
                             input=kept, capture_output=True, text=True, timeout=20, errors="replace")
    except subprocess.TimeoutExpired:
        raise CheckFailed("the C preprocessor did not finish on your file (a macro that expands without end?)")
    if run.returncode != 0 or len(run.stdout) > MAX_SOURCE_SIZE:
        first = (run.stderr.strip().splitlines() or ["its output is too large"])[0]
        raise CheckFailed(f"the C preprocessor refused your file: {first}")
    code, directives = [], []
    names = {o[2:].split("=")[0] for o in options} | _predefined(cpp)
    for line in run.stdout.splitlines():
        m = re.match(r"\s*#\s*(define|undef)\s+(\w+)", line)
        if not m:
            code.append(line)
        elif m.group(2) not in names and not m.group(2).startswith("grade_") and not _ATOMIC.fullmatch(m.group(2)):
            directives.append(line)   # the grader's names and the atomics stay out of the student's reach
    return includes, "\n".join(code), "\n".join(directives)


def tokens(code):
    return _TOKEN.findall(code)


def _matching(toks, i):
    """Index of the bracket closing the one at toks[i]."""
    pairs = {"(": ")", "{": "}", "[": "]"}
    opening, closing, depth = toks[i], pairs[toks[i]], 0
    for j in range(i, len(toks)):
        depth += (toks[j] == opening) - (toks[j] == closing)
        if depth == 0:
            return j
    raise CheckFailed(f"unbalanced {opening!r} in your file")


def _next(toks, i):
    """Index of the first token after i that is not white space."""
    i += 1
    while i < len(toks) and toks[i].isspace():
        i += 1
    return i


def definitions(toks):
    """{function name: (index of its name, of its parameters' '(', of its body's '{' and '}')} at file scope."""
    found, i, depth = {}, 0, 0
    while i < len(toks):
        t = toks[i]
        if t == "{":
            depth += 1
        elif t == "}":
            depth -= 1
        elif depth == 0 and re.match(r"[A-Za-z_]", t):
            p = _next(toks, i)
            if p < len(toks) and toks[p] == "(":
                close = _matching(toks, p)
                b = _next(toks, close)
                if b < len(toks) and toks[b] == "{":
                    end = _matching(toks, b)
                    found[t] = (i, p, b, end)
                    i = end
        i += 1
    return found


def _declaration_start(toks, i):
    """Index of the first token of the declaration whose name is toks[i] (its return type,
    `static inline`, attributes): just after the previous `;`, `}` or directive line."""
    while i > 0 and toks[i - 1] not in (";", "}", "#"):
        i -= 1
    if i > 0 and toks[i - 1] == "#":   # a #pragma line that cpp kept: start on the line after it
        while i < len(toks) and "\n" not in toks[i]:
            i += 1
    return i


def _has_loop(toks, start, end):
    return any(t in _LOOPS for t in toks[start:end])


def counted_copy(code, name, what):
    """A copy of function `name` of the expanded `code`, named grade_counted_NAME, with one more
    parameter `int* grade_iterations` that each round of each of its loops adds one to (a `goto`
    counts as a round). A function of the student's that it calls and that has a loop of its
    own is refused: its rounds would not be counted. `what` names the function in messages."""
    toks = tokens(code)
    defined = definitions(toks)
    if name not in defined:
        raise CheckFailed(f"{what} is not defined in your file (keep its name and signature)")
    start, params, body, end = defined[name]
    _refuse_looping_calls(toks, defined, name, what)
    out = list(toks)
    out[start] = f"grade_counted_{name}"
    start = _declaration_start(toks, start)   # the copy keeps its return type and qualifiers
    close = _matching(toks, params)
    out[close] = f", int* {COUNTER})"
    i = body
    while i < end:
        t = toks[i]
        if t in ("for", "while") and toks[_next(toks, i)] == "(":
            p = _next(toks, i)
            _count_condition(toks, out, p, _matching(toks, p), t == "for")
        elif t == "goto":
            semicolon = toks.index(";", i)
            out[i], out[semicolon] = "{ " + _TICK + "; goto", "; }"
        i += 1
    return "".join(out[start:end + 1])


def _count_condition(toks, out, open_, close, is_for):
    """Make the loop's condition (toks[open_ + 1 : close]) tick first."""
    if not is_for:
        out[open_], out[close] = f"({_TICK} && (", "))"
        return
    depth, semicolons = 0, []
    for j in range(open_ + 1, close):
        depth += (toks[j] in ("(", "[", "{")) - (toks[j] in (")", "]", "}"))
        if toks[j] == ";" and depth == 0:
            semicolons.append(j)
    first, second = semicolons[:2]
    condition = "".join(toks[first + 1:second]).strip()
    out[first + 1:second] = [f" {_TICK} && ({condition or 1})"] + [""] * (second - first - 2)


def _refuse_looping_calls(toks, defined, name, what, seen=None):
    seen = seen or {name}
    _, _, body, end = defined[name]
    for j in range(body, end):
        callee = toks[j]
        if callee in defined and callee not in seen and toks[_next(toks, j)] == "(":
            seen.add(callee)
            if _has_loop(toks, defined[callee][2], defined[callee][3]):
                raise CheckFailed(f"{what} calls {callee}, which has a loop of its own: keep the loop in {what} "
                                  "itself, so that its rounds can be counted")
            _refuse_looping_calls(toks, defined, callee, what, seen)


# The atomics' first argument goes through grade_counted(): on the global counter it counts one
# atomic in the int after the counter (the grader reads it), elsewhere it passes the pointer on.
ATOMIC_PRELUDE = r"""
#define GRADE_COUNTED_GLOBAL(T) __attribute__((overloadable)) static inline volatile __global T* \
    grade_counted(volatile __global T* p) { atomic_inc((volatile __global int*)p + 1); return p; }
#define GRADE_PASSED(Q, T) __attribute__((overloadable)) static inline Q T* grade_counted(Q T* p) { return p; }
GRADE_COUNTED_GLOBAL(int)
GRADE_COUNTED_GLOBAL(uint)
GRADE_PASSED(volatile __local, int)
GRADE_PASSED(volatile __local, uint)
GRADE_PASSED(volatile __global, float)
GRADE_PASSED(volatile __local, float)
#if defined(__OPENCL_C_VERSION__) && __OPENCL_C_VERSION__ >= 200
GRADE_COUNTED_GLOBAL(atomic_int)
GRADE_COUNTED_GLOBAL(atomic_uint)
GRADE_PASSED(volatile __local, atomic_int)
GRADE_PASSED(volatile __local, atomic_uint)
#endif
"""


def counted_atomics(code):
    """The expanded `code` with the pointer of every atomic read-modify-write passed through grade_counted()."""
    toks = tokens(code)
    out = list(toks)
    for i, t in enumerate(toks):
        if _ATOMIC.fullmatch(t) and not _NOT_RMW.search(t):
            p = _next(toks, i)
            if p >= len(toks) or toks[p] != "(":
                raise CheckFailed(f"{t} is used without a call (its address taken?): call atomics directly")
            depth, j = 0, p + 1
            while j < len(toks) and not (depth == 0 and toks[j] in (",", ")")):
                depth += (toks[j] in ("(", "[", "{")) - (toks[j] in (")", "]", "}"))
                j += 1
            out[p] = out[p] + "grade_counted("
            out[j] = ")" + out[j]
    return "".join(out)


def assemble(includes, *parts):
    """The text of an instrumented file: the student's includes, then the parts."""
    return "\n".join(list(includes) + [p for p in parts if p]) + "\n"
