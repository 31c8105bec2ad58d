"""Integer formulas written once, in Python, and emitted as C helpers into layout.h.

An index the host and the kernels both compute (which strategy a connection is, where a record
goes, which random number a vertex reads) is one Python function of its arguments. The host calls
it with ints or numpy arrays; `c_helper()` calls it with `Var`s, symbols whose arithmetic writes C
text instead of computing, and so gets the C function's body from the same code. Only + - * // %
and comparisons are needed, and `where()` for a choice (numpy's where; C's ?:). C's `/` and `%`
truncate where Python's `//` and `%` floor: the formulas are used on non-negative values, where
both agree (tests/test_shared_indices.py compares the two over ranges of inputs).
"""
import numpy as np

# How every generated helper is declared, as every helper in cl/ (cl/common.h says why).
HELPER = "HELPER"   # the macro of cl/common.h: static inline __attribute__((always_inline))


class Var:
    """A C expression: arithmetic on it builds a bigger expression (the text, fully parenthesized)."""

    def __init__(self, text):
        self.text = text

    def __str__(self):
        return self.text

    def _op(self, op, other, swap=False):
        a, b = (other, self) if swap else (self, other)
        return Var(f"({a} {op} {b})")

    def __add__(self, o): return self._op("+", o)
    def __radd__(self, o): return self._op("+", o, True)
    def __sub__(self, o): return self._op("-", o)
    def __rsub__(self, o): return self._op("-", o, True)
    def __mul__(self, o): return self._op("*", o)
    def __rmul__(self, o): return self._op("*", o, True)
    def __floordiv__(self, o): return self._op("/", o)
    def __rfloordiv__(self, o): return self._op("/", o, True)
    def __mod__(self, o): return self._op("%", o)
    def __rmod__(self, o): return self._op("%", o, True)
    def __le__(self, o): return self._op("<=", o)
    def __lt__(self, o): return self._op("<", o)
    def __ge__(self, o): return self._op(">=", o)
    def __gt__(self, o): return self._op(">", o)


def where(condition, if_true, if_false):
    """numpy.where on the host; `condition ? if_true : if_false` in C."""
    if any(isinstance(x, Var) for x in (condition, if_true, if_false)):
        return Var(f"({condition} ? {if_true} : {if_false})")
    return np.where(condition, if_true, if_false)


def c_defines(group, prefix):
    """`#define PREFIX_NAME value` for every member of an IntEnum, under its docstring."""
    return "\n".join([f"/* {group.__doc__} */"] + [f"#define {prefix}{m.name} {int(m) if m >= 0 else f'({int(m)})'}" for m in group])


def c_helper(function, params, returns="int", outputs=None, doc=None):
    """The C helper computing `function` (a Python function of the parameters `params`, [(name,
    C type)]). A function that returns a tuple becomes a void helper writing through the pointers
    `outputs` ([(name, C type)]), in order. `doc`: the comment above it (default: the docstring's
    first line)."""
    result = function(*(Var(name) for name, _ in params))
    doc = doc or (function.__doc__ or "").strip().split("\n")[0]
    signature = ", ".join(f"{t} {n}" for n, t in params + [(n, f"{t}*") for n, t in outputs or []])
    if outputs:
        body = " ".join(f"*{n} = ({t}){_wrapped(v)};" for (n, t), v in zip(outputs, result))
        line = f"{HELPER} void {function.__name__}({signature}) {{ {body} }}"
    else:
        line = f"{HELPER} {returns} {function.__name__}({signature}) {{ return ({returns}){_wrapped(result)}; }}"
    return (f"/* {doc} (toolkit/core/{function.__module__.rsplit('.', 1)[-1]}.py) */\n" if doc else "") + line


def _wrapped(value):
    """`value` in parentheses (an operation's text already has them)."""
    text = str(value)
    return text if isinstance(value, Var) and text.startswith("(") else f"({text})"
