r"""The generated files: one header, the law's C file, CasADi's code and the host driver.

* ``ilc_law.h`` — the one header: sizes, ``ilc_real``, the status codes, the work struct
  (``ilc_work_t``), the state between trials (``ilc_state_t``) and the in-trial step
  (``ilc_step_t``) where the law has them, the functions; its comment names the design, its
  fingerprint and the certificate it carries;
* ``ilc_law.c`` — the constants (``static const``: flash), the stages (``static``) and the
  public functions; fixed sizes, no recursion, no allocation, ``const`` inputs, loops of fixed
  length only (deterministic time per call);
* ``ilc_forgetting.c`` / ``ilc_forgetting_casadi.inc`` — a variable forgetting factor: CasADi's
  code of the law's own expression, included by a wrapper that sets ``casadi_real`` to
  ``ilc_real`` (and quiets the unused parameters of CasADi's calling convention);
* ``ilc_host.c`` — the test driver with a ``main``: ``ilc_host INPUT.csv RECORD.csv`` prints
  the next input in ``learn --out``'s CSV format (:mod:`ilc_analysis.export._host`).

``cc -std=c99 -O2 *.c -lm -o ilc_host`` in the directory builds the driver; a machine's
firmware takes ``ilc_law.h``, ``ilc_law.c`` (and the forgetting files) only.
"""

from __future__ import annotations

from ._c import PRECISIONS, CArray, c_string, comment_text, literal
from ._host import host_source
from ._plan import TimeReversalUpdate, UpdatePlan
from ._signals import CASADI_FORGETTING, FeedbackStage, ForgettingStage

__all__ = ["generate_sources", "HEADER", "LAW_SOURCE", "HOST_SOURCE", "FIRMWARE_SOURCES"]

HEADER = "ilc_law.h"
LAW_SOURCE = "ilc_law.c"
HOST_SOURCE = "ilc_host.c"
FORGETTING_SOURCE = "ilc_forgetting.c"
FORGETTING_INCLUDE = "ilc_forgetting_casadi.inc"
#: The sources a machine's firmware compiles (the host driver aside).
FIRMWARE_SOURCES = (LAW_SOURCE, FORGETTING_SOURCE)


def _comment_block(lines: list[str]) -> str:
    body = "\n".join(f" * {comment_text(line)}".rstrip() for line in lines)
    return f"/*\n{body}\n */\n"


def _struct(name: str, members: list[tuple[str, str, str]], what: str) -> str:
    rows = "\n".join(f"    {ctype} {member};   /* {comment_text(c)} */"
                     for ctype, member, c in members)
    return f"/* {comment_text(what)} */\ntypedef struct {{\n{rows}\n}} {name};\n"


def _work_members(plan: UpdatePlan) -> list[tuple[str, str, str]]:
    members = [("ilc_real", f"{w.name}[{w.length}]", w.comment) for w in plan.work()]
    return members or [("ilc_real", "reserved[1]", "unused (the law needs no work arrays)")]


def _forgetting_stage(plan: UpdatePlan) -> ForgettingStage | None:
    return next((s for s in plan.all_stages()
                 if isinstance(s, ForgettingStage) and s.variable), None)


def generate_sources(plan: UpdatePlan, problem, precision: str, info: dict) -> dict[str, str]:
    """The files of the export (module docstring), by name.

    Parameters
    ----------
    plan : UpdatePlan
        The law's generated update.
    problem : ILCProblem
        The design's problem (sizes, names, reference, initial input).
    precision : {'double', 'single'}
        ``ilc_real`` is ``double`` or ``float``.
    info : dict
        What the header names: ``title``, ``lines`` (the design, certificate and fingerprint
        lines), ``fingerprint``.
    """
    files = {HEADER: _header(plan, problem, precision, info),
             LAW_SOURCE: _law_source(plan, problem, precision, info),
             HOST_SOURCE: host_source(plan, problem, precision)}
    forgetting = _forgetting_stage(plan)
    if forgetting is not None:
        files[FORGETTING_INCLUDE] = forgetting.casadi_source(precision)
        files[FORGETTING_SOURCE] = _forgetting_wrapper(info)
    return files


def _header(plan: UpdatePlan, problem, precision: str, info: dict) -> str:
    real = PRECISIONS[precision]
    usage = [
        "",
        "Between trials, on the machine (no allocation: the caller owns every array):",
        "    static ilc_work_t work;",
        "    static ilc_real ff[ILC_INPUT_SIZE], record[ILC_RECORD_SIZE], next[ILC_INPUT_SIZE];",
    ]
    state = plan.stateful is not None
    if state:
        usage += ["    static ilc_state_t state;",
                  "    ilc_state_init(&state);"]
    usage += ["    ilc_first_input(ff);",
              "    for each run: apply ff at t0 + k ts (k = 0..N-1), log y(k) for "
              "k = 0..N+s-1 into",
              "        record[k * ILC_NY + j];",
              ("        if (ilc_update(ff, record, &state, &work, next) != ILC_OK) stop "
               "learning;" if state else
               "        if (ilc_update(ff, record, &work, next) != ILC_OK) stop learning;"),
              "        copy next into ff (the next run's input)."]
    if plan.feedback is not None:
        usage += ["During a trial the machine's loop adds the current-trial feedback, per "
                  "sample:",
                  "    ilc_step_start(&step);  then at each k: ilc_step(&step, k, &ff[k * "
                  "ILC_NU], y_k, u_k); apply u_k."]
    if state:
        usage += ["ilc_state_t is the state between runs: keep it (e.g. in retained RAM) "
                  "from one call to the next."]
    lines = [f"{HEADER} -- {info['title']}", "", *info["lines"], *usage]
    macros = {"ILC_N": f"{problem.N}u", "ILC_NU": f"{problem.n_u}u",
              "ILC_NY": f"{problem.n_y}u", "ILC_SHIFT": f"{problem.shift}u"}
    macro_text = "\n".join(f"#define {k} {v}" for k, v in macros.items())
    parts = [_comment_block(lines), "#ifndef ILC_LAW_H\n#define ILC_LAW_H\n",
             "#include <stddef.h>\n#include <stdint.h>\n",
             "/* the trial: N samples of the input, N + s of the record, n_u inputs, n_y outputs "
             "*/",
             macro_text,
             "#define ILC_RECORD (ILC_N + ILC_SHIFT)",
             "#define ILC_INPUT_SIZE (ILC_N * ILC_NU)",
             "#define ILC_RECORD_SIZE (ILC_RECORD * ILC_NY)",
             f"#define ILC_TS {literal(problem.ts, precision)}   /* sample time [s] */\n",
             f"/* the arithmetic of the update: {precision} precision */",
             f"typedef {real} ilc_real;",
             "#define ILC_0 ((ilc_real)0)\n#define ILC_1 ((ilc_real)1)\n"
             "#define ILC_2 ((ilc_real)2)\n#define ILC_HALF ((ilc_real)0.5)\n",
             "/* status of ilc_update and ilc_step */",
             "#define ILC_OK 0          /* done */",
             "#define ILC_NOT_FINITE 1  /* the next input is not finite: the learning diverges,"
             " or the record holds a non-finite value; keep the last input */",
             "#define ILC_BAD_SAMPLE 2  /* ilc_step: k outside 0..N-1 */",
             "#define ILC_BAD_STATE 3   /* ilc_update: a corrupted state between runs */\n",
             _struct("ilc_work_t", _work_members(plan),
                     "work arrays of ilc_update (their values between calls do not matter)")]
    if plan.stateful is not None:
        parts.append(_struct("ilc_state_t", [(t, m, c) for t, m, c in
                                              plan.stateful.state_members()],
                             "the law's state between runs (what learn's state file holds: "
                             "the iteration, the pending extra experiment and what it needs)"))
    if plan.feedback is not None:
        parts.append(_struct("ilc_step_t", [("ilc_real", "e_prev[ILC_NY]",
                                             "the error at the previous sample")],
                             "the in-trial step's memory (one trial)"))
    parts += [
        "/* the design's fingerprint (learn's state file carries the same) */",
        "extern const char ilc_fingerprint[];",
        "/* the channel names (the CSV headers of learn) */",
        "extern const char *const ilc_input_names[ILC_NU];",
        "extern const char *const ilc_output_names[ILC_NY];\n",
        "/* the first trial's input (the problem's initial input) */",
        "void ilc_first_input(ilc_real u[ILC_INPUT_SIZE]);\n"]
    if state:
        parts += ["/* the state before the first run (iteration 1, the trial pending) */",
                  "void ilc_state_init(ilc_state_t *state);\n",
                  "/* the next run's input from the last run's input and record (a trial or "
                  "an extra experiment, as state says) */",
                  "int ilc_update(const ilc_real input[ILC_INPUT_SIZE], const ilc_real "
                  "record[ILC_RECORD_SIZE],\n               ilc_state_t *state, ilc_work_t "
                  "*work, ilc_real next[ILC_INPUT_SIZE]);\n"]
    else:
        parts += ["/* between trials: the next trial's input from the last trial's input "
                  "and its record */",
                  "int ilc_update(const ilc_real input[ILC_INPUT_SIZE], const ilc_real "
                  "record[ILC_RECORD_SIZE],\n               ilc_work_t *work, ilc_real "
                  "next[ILC_INPUT_SIZE]);\n"]
    if plan.feedback is not None:
        parts += ["/* in the trial: start, then at each sample k = 0..N-1 the input to apply "
                  "from the feed-forward and y(k) */",
                  "void ilc_step_start(ilc_step_t *step);",
                  "int ilc_step(ilc_step_t *step, size_t k, const ilc_real ff_k[ILC_NU], "
                  "const ilc_real y_k[ILC_NY],\n             ilc_real u_k[ILC_NU]);\n"]
    parts.append("#endif /* ILC_LAW_H */\n")
    return "\n".join(parts)


def _names(name: str, names) -> str:
    items = ", ".join(c_string(n) for n in names)
    return f"const char *const {name}[] = {{{items}}};"


def _law_source(plan: UpdatePlan, problem, precision: str, info: dict) -> str:
    initial = CArray("ilc_initial_input", problem.initial_input(),
                     "the first trial's input (the problem's initial input), [k][i]")
    constants = [initial, *plan.constants()]
    if plan.stateful is not None:
        constants += plan.stateful.constants()
    private = "\n".join(f"#define {k} {v}" for k, v in plan.all_macros(precision).items())
    stages = plan.all_stages()
    functions = []
    seen = set()
    for s in stages:
        if s.function_name not in seen:
            seen.add(s.function_name)
            functions.append(s.function())
    head = [_comment_block([f"{LAW_SOURCE} -- {info['title']}", "",
                            "What ilc_update computes, in order:",
                            *[f"  {i + 1}. {s.description()}" for i, s in enumerate(stages)],
                            *(["  then: " + n for n in plan.notes])]),
            "#include <math.h>\n#include <stddef.h>\n",
            f'#include "{HEADER}"\n']
    if private:
        head.append(private + "\n")
    if _forgetting_stage(plan) is not None:
        head.append(f"/* CasADi's code of the variable forgetting factor ({FORGETTING_SOURCE}) "
                    f"*/\nint {CASADI_FORGETTING}(const ilc_real **arg, ilc_real **res, int *iw, "
                    f"ilc_real *w, int mem);\n")
    body = [c.definition(precision) for c in constants]
    body.append(f"const char ilc_fingerprint[] = {c_string(info['fingerprint'])};")
    body.append(_names("ilc_input_names", problem.input_names))
    body.append(_names("ilc_output_names", problem.output_names) + "\n")
    body += functions
    if plan.stateful is not None:
        body.append(plan.stateful.function())
    body.append("""\
void ilc_first_input(ilc_real u[ILC_INPUT_SIZE])
{
    size_t i;
    for (i = 0u; i < ILC_INPUT_SIZE; ++i) {
        u[i] = ilc_initial_input[i];
    }
}
""")
    if plan.stateful is not None:
        body.append(_state_init(plan.stateful))
        body.append("int ilc_update(const ilc_real input[ILC_INPUT_SIZE], const ilc_real "
                    "record[ILC_RECORD_SIZE],\n               ilc_state_t *state, ilc_work_t "
                    "*work, ilc_real next[ILC_INPUT_SIZE])\n{\n"
                    + plan.stateful.update_body() + "}\n")
    else:
        calls = "\n".join(f"    {s.call()}" for s in stages)
        unused = ("    (void)work;\n" if not any("work" in s.call() for s in stages) else "")
        body.append(f"""\
int ilc_update(const ilc_real input[ILC_INPUT_SIZE], const ilc_real record[ILC_RECORD_SIZE],
               ilc_work_t *work, ilc_real next[ILC_INPUT_SIZE])
{{
    size_t i;
{unused}{calls}
    for (i = 0u; i < ILC_INPUT_SIZE; ++i) {{
        if (!isfinite(next[i])) {{
            return ILC_NOT_FINITE;
        }}
    }}
    return ILC_OK;
}}
""")
    if plan.feedback is not None:
        body.append(_step_functions(plan.feedback))
    return "\n".join(head) + "\n" + "\n".join(body)


def _state_init(stateful: TimeReversalUpdate) -> str:
    arrays = [m for _, m, _ in stateful.state_members() if "[" in m]
    loops = "\n".join(f"    for (i = 0u; i < {m.split('[')[1].rstrip(']')}u; ++i) {{\n"
                      f"        state->{m.split('[')[0]}[i] = ILC_0;\n    }}" for m in arrays)
    return f"""\
void ilc_state_init(ilc_state_t *state)
{{
    size_t i;
    state->iteration = 1u;
    state->experiment = 0u;
{loops}
}}
"""


def _step_functions(fb: FeedbackStage) -> str:
    return f"""\
void ilc_step_start(ilc_step_t *step)
{{
    size_t j;
    for (j = 0u; j < ILC_NY; ++j) {{
        step->e_prev[j] = ILC_0;
    }}
}}

int ilc_step(ilc_step_t *step, size_t k, const ilc_real ff_k[ILC_NU], const ilc_real y_k[ILC_NY],
             ilc_real u_k[ILC_NU])
{{
    ilc_real et[ILC_NY];
    size_t i, j;
    if (k >= ILC_N) {{
        return ILC_BAD_SAMPLE;
    }}
    for (j = 0u; j < ILC_NY; ++j) {{      /* e(k) = y_d(k - s) - y(k), zero before the window */
        et[j] = (k >= ILC_SHIFT) ? ilc_reference[(k - ILC_SHIFT) * ILC_NY + j] - y_k[j] : ILC_0;
    }}
    for (i = 0u; i < ILC_NU; ++i) {{
        ilc_real acc_p = ILC_0;
        ilc_real acc_d = ILC_0;
        for (j = 0u; j < ILC_NY; ++j) {{
            acc_p += {fb.psi2.entry("k", "i", "j")} * et[j];
            acc_d += {fb.phi2.entry("k", "i", "j")} * ((et[j] - step->e_prev[j]) / ILC_TS);
        }}
        u_k[i] = (ff_k[i] + acc_p) + acc_d;
    }}
    for (j = 0u; j < ILC_NY; ++j) {{
        step->e_prev[j] = et[j];
    }}
    return ILC_OK;
}}
"""


def _forgetting_wrapper(info: dict) -> str:
    return (_comment_block([
        f"{FORGETTING_SOURCE} -- {info['title']}", "",
        "The variable forgetting factor of eq (12), a(e) = (1 - delta) 5^(-Lambda max_j e_j^2),",
        "evaluated as (1 - delta) exp(-(sqrt(r) min(max_j |e_j|, cap))^2), r = Lambda ln 5, "
        "with the",
        "cap where exp underflows (no overflow for any finite error): CasADi's code "
        f"({FORGETTING_INCLUDE})",
        "of the law's own expression (VariableForgetting.casadi_factor), with casadi_real = "
        "ilc_real.",
        "CasADi's calling convention has parameters this function does not use: their "
        "warning is off here."])
        + f'#include "{HEADER}"\n\n#define casadi_real ilc_real\n#define casadi_int int\n\n'
        "#if defined(__GNUC__)\n#pragma GCC diagnostic push\n"
        '#pragma GCC diagnostic ignored "-Wunused-parameter"\n#endif\n'
        f'#include "{FORGETTING_INCLUDE}"\n'
        "#if defined(__GNUC__)\n#pragma GCC diagnostic pop\n#endif\n")
