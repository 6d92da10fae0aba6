"""A C guard around pythonfmu's FMI shim: the FMI state machine enforced, misuse answered
with an error status and a log line instead of a crash.

pythonfmu's shims (FMI 2: pythonfmu 0.7, FMI 3: pythonfmu3 0.3.4) trust the host: a
second ``freeInstance`` deletes the instance twice (FMI 2: abort, "double free"; FMI 3:
SIGSEGV), and any Python exception becomes a Fatal status that kills the instance, so a
parameter set after initialisation or a second ``exitInitializationMode`` could only be
fatal or silently accepted. :func:`guard_source` generates a small C library that
exports every function of the FMI version (the definitions are generated from the
``fmi2FunctionTypes.h`` / ``fmi3FunctionTypes.h`` headers fmpy ships) and forwards each
call to the shim, renamed ``<modelIdentifier>_pythonfmu.so`` beside it, after checking:

* the instance pointer: one the guard handed out and did not free (a second
  ``freeInstance`` or any call after it is refused, with a line on stderr: the host's
  logger is no longer valid then); instances are never reused, so a stale pointer never
  reaches a live one;
* the state (instantiated, initialisation mode, step mode, terminated, failed):
  ``setupExperiment``/``enterInitializationMode`` only once after instantiation or
  reset; ``exitInitializationMode`` only in initialisation mode; ``doStep`` only in step
  mode; a second ``terminate`` is accepted and does nothing; after a Fatal status every
  call but ``freeInstance`` is refused;
* the experiment start time: navsim's FMUs start at t = 0 (time is the tick count since
  the episode start), any other start time is refused;
* parameters (value references compiled in from the variable table) set after
  initialisation are refused (``reset`` first);
* a bad parameter value: instead of raising, the slave passes its message (the
  parameter, the expectation, the value) to the guard's exported
  ``navsim_guard_refuse(msg)`` (:func:`navsim.fmu.runtime.refuse_through_guard`), and the
  guard answers that ``exitInitializationMode`` with an error status (not pythonfmu's
  Fatal) and logs the message itself (pythonfmu forwards messages only with logging on);
  the instance stays in initialisation mode, so the host may set a valid value and call
  it again, or reset;

* failed instances: ``freeInstance`` of an instance that returned a Fatal status is not
  forwarded to the shim (the C++ instance and its Python objects are kept for the rest of
  the process). pythonfmu's shims turn a Python exception into Fatal and, doing so,
  release their references to the slave class, the slave instance and its log queue
  (``handle_py_exception`` -> ``cleanPyObject``) without clearing the pointers; the
  instance's destructor releases them again. Freeing a failed instance therefore
  dropped references it did not own, and the objects were freed while still in use: a
  corrupted heap found at the interpreter's exit (SIGSEGV or "corrupted double-linked
  list" in the final garbage collection of a Python host). Together with the extra
  references :func:`navsim.fmu.runtime.mark_failed` keeps, the counts stay balanced;
* the shim's exit: pythonfmu keeps its interpreter state in a static
  ``std::shared_ptr<PyState>`` that an ELF destructor (``finalizePythonInterpreter``)
  resets after the C++ exit handlers have destroyed it, a second release of freed
  memory when the shim is still loaded at exit; the guard calls
  ``finalizePythonInterpreter`` itself from an exit handler registered after the shim
  is loaded (it runs first) and keeps itself loaded (``RTLD_NODELETE``) so that the
  handler only runs at exit;

each refusal returns ``fmi2Error``/``fmi3Error`` and logs one error-category line
through the host's logger. :func:`compile_guard` builds it with gcc (Linux); without a
compiler or the headers the FMU carries the bare shim (``navsim_fmu.json``:
``"guard": false``) and behaves as before.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

__all__ = ["guard_source", "compile_guard", "headers_dir"]

_STATE_FUNCS = {
    # name without prefix -> (allowed states, transition on success or None)
    "SetupExperiment": ("S_INST", None),
    "EnterInitializationMode": ("S_INST", "S_INIT"),
    "ExitInitializationMode": ("S_INIT", "S_RUN"),
    "DoStep": ("S_RUN", None),
}
_SETTERS = {"SetReal", "SetInteger", "SetBoolean", "SetString", "SetFloat64", "SetFloat32", "SetInt8", "SetUInt8",
            "SetInt16", "SetUInt16", "SetInt32", "SetUInt32", "SetInt64", "SetUInt64", "SetBinary", "SetClock"}
_STATE_TEXT = '{"instantiated", "initialisation mode", "step mode", "terminated", "failed"}'


def headers_dir() -> Path | None:
    """fmpy's copy of the FMI headers, or None."""
    try:
        import fmpy
    except ImportError:
        return None
    folder = Path(fmpy.__file__).parent / "c-code"
    return folder if (folder / "fmi2FunctionTypes.h").exists() else None


def _signatures(header: str, fmi: int) -> list[tuple[str, str, list[tuple[str, str]]]]:
    """(return type, name, [(declaration, argument name)]) of every ``typedef ... fmiXyTYPE(...)``."""
    text = re.sub(r"/\*.*?\*/", "", header, flags=re.S)
    out = []
    for ret, name, params in re.findall(rf"typedef\s+([\w\s\*]+?)\s*\b(fmi{fmi}\w+?)TYPE\s*\(([^;]*?)\)\s*;", text):
        if "Callback" in name:
            continue
        args = []
        plist = [p.strip() for p in params.split(",")] if params.strip() not in ("", "void") else []
        for i, p in enumerate(plist):
            array = p.endswith("[]")
            core = p[:-2].strip() if array else p
            tokens = re.findall(r"[A-Za-z_]\w*", core)
            if len(tokens) == 1 or tokens[-1] in ("const",) or core.endswith("*"):
                arg = f"a{i}"
                decl = f"{core} {arg}" + ("[]" if array else "")
            else:
                arg = tokens[-1]
                decl = p
            args.append((decl, arg))
        out.append((" ".join(ret.split()), name, args))
    return out


def guard_source(fmi: int, parameter_vrs: list[int], header_dir: Path, shim_name: str) -> str:
    """The guard's C source for one FMU (see the module docstring)."""
    p = f"fmi{fmi}"
    sigs = _signatures((header_dir / f"{p}FunctionTypes.h").read_text(encoding="utf-8", errors="replace"), fmi)
    inst_type = "fmi2Component" if fmi == 2 else "fmi3Instance"
    params = ", ".join(str(v) for v in sorted(set(parameter_vrs))) or "0"
    if fmi == 2:
        log_fields = "const fmi2CallbackFunctions* cb;"
        log_call = ('if (g && g->cb && g->cb->logger) g->cb->logger(g->cb->componentEnvironment, g->name, '
                    '(fmi2Status)status, status >= 3 ? "logStatusError" : "logAll", safe);')
    else:
        log_fields = "fmi3InstanceEnvironment env; fmi3LogMessageCallback log;"
        log_call = ('(void)safe;  /* FMI 3 passes the message itself */\n    '
                    'if (g && g->log) g->log(g->env, (fmi3Status)status, status >= 3 ? "logStatusError" : "logAll", '
                    'msg);')
    lines = [f'''/* Generated by navsim (navsim/fmu/guard.py): the FMI {fmi} state machine around pythonfmu's shim. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "{p}Functions.h"

enum {{ S_INST, S_INIT, S_RUN, S_TERM, S_FATAL }};
static const char* STATE_NAME[] = {_STATE_TEXT};
static const unsigned int PARAM_VRS[] = {{ {params} }};
static const size_t N_PARAM_VRS = {len(set(parameter_vrs))};

typedef struct Guard {{
    {inst_type} inner;
    int state, freed;
    char name[256];
    {log_fields}
    struct Guard* next;
}} Guard;

static Guard* registry = NULL;
static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;
static void* shim = NULL;
static __thread int refused = 0;  /* set by the slave (navsim_guard_refuse) during the call it refuses */
static __thread char refused_msg[1024];

void navsim_guard_refuse(const char* msg);
void navsim_guard_refuse(const char* msg) {{ refused = 1; snprintf(refused_msg, sizeof refused_msg, "%s", msg ? msg : ""); }}

static void (*shim_finalize)(void) = NULL;
static void finalize_shim_at_exit(void) {{ if (shim_finalize) shim_finalize(); }}

static void* real(const char* name)
{{
    if (!shim) {{
        Dl_info info;
        char path[4096];
        if (!dladdr((void*)&real, &info) || !info.dli_fname) return NULL;
        snprintf(path, sizeof path, "%s", info.dli_fname);
        char* slash = strrchr(path, '/');
        snprintf(slash ? slash + 1 : path, sizeof path - (size_t)(slash ? slash + 1 - path : 0), "%s", "{shim_name}");
        shim = dlopen(path, RTLD_NOW | RTLD_LOCAL);
        if (!shim) {{ fprintf(stderr, "navsim FMU: cannot load %s: %s\\n", path, dlerror()); return NULL; }}
        /* pythonfmu resets its static PyState from an ELF destructor that runs after the C++
           exit handlers destroyed it (a second release at exit): reset it first, from an exit
           handler registered after the shim's, with this library kept loaded until exit */
        *(void**)(&shim_finalize) = dlsym(shim, "finalizePythonInterpreter");
        if (shim_finalize) {{
            dlopen(info.dli_fname, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
            atexit(finalize_shim_at_exit);
        }}
    }}
    return dlsym(shim, name);
}}

static void say(Guard* g, int status, const char* fmt, ...)
{{
    char msg[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    char safe[2048];  /* the message is the logger's format: '%' doubled, so any logger prints it as is */
    size_t j = 0;
    for (size_t i = 0; msg[i] && j + 2 < sizeof safe; i++) {{
        if (msg[i] == '%') safe[j++] = '%';
        safe[j++] = msg[i];
    }}
    safe[j] = 0;
    {log_call}
    else fprintf(stderr, "navsim FMU %s: %s\\n", g ? g->name : "?", msg);
}}

static Guard* find(void* c, const char* fn)
{{
    Guard* g;
    pthread_mutex_lock(&lock);
    for (g = registry; g && (void*)g != c; g = g->next) {{}}
    pthread_mutex_unlock(&lock);
    if (!g) {{ fprintf(stderr, "navsim FMU: %s called with an instance this FMU did not create (%p); refused\\n", fn, c); return NULL; }}
    if (g->freed) {{ fprintf(stderr, "navsim FMU %s: %s called after freeInstance; refused\\n", g->name, fn); return NULL; }}
    return g;
}}

static Guard* wrap({inst_type} inner, const char* name)
{{
    if (!inner) return NULL;
    Guard* g = (Guard*)calloc(1, sizeof(Guard));
    g->inner = inner;
    snprintf(g->name, sizeof g->name, "%s", name ? name : "");
    pthread_mutex_lock(&lock);
    g->next = registry;
    registry = g;
    pthread_mutex_unlock(&lock);
    return g;
}}

static int is_parameter(unsigned int vr)
{{
    for (size_t i = 0; i < N_PARAM_VRS; i++) if (PARAM_VRS[i] == vr) return 1;
    return 0;
}}
''']
    for ret, name, args in sigs:
        short = name[4:]
        decl = ", ".join(d for d, _ in args) or "void"
        names = [a for _, a in args]
        ptr = f"(({ret} (*)({decl}))fp)"
        body = [f"{ret} {name}({decl})", "{", "    static void* fp = NULL;", f"    if (!fp) fp = real(\"{name}\");"]
        if short.startswith("Instantiate"):
            body.append(f"    {inst_type} inner = {ptr} ? {ptr}({', '.join(names)}) : NULL;")
            body.append(f"    Guard* g = wrap(inner, {names[0]});")
            if fmi == 2:
                body.append("    if (g) g->cb = functions;")
            elif "logMessage" in names:
                body.append("    if (g) { g->env = instanceEnvironment; g->log = logMessage; }")
            body += [f"    return ({inst_type})g;", "}"]
        elif short == "FreeInstance":
            body += [f"    Guard* g = find((void*){names[0]}, \"{name}\");",
                     "    if (!g) return;",
                     "    /* a failed instance is not handed to the shim: see 'Failed instances' above */",
                     f"    if (g->state != S_FATAL && {ptr}) {ptr}(g->inner);",
                     "    g->freed = 1;  /* the Guard itself is kept: a stale pointer is recognised, never reused */",
                     "}"]
        elif not args or not args[0][0].startswith(inst_type):
            call = f"{ptr}({', '.join(names)})"
            body += [f"    return {call};", "}"] if ret != "void" else [f"    {call};", "}"]
        else:
            fwd = ", ".join(["g->inner"] + names[1:])
            err = "(fmi2Status)3" if fmi == 2 else "(fmi3Status)3"
            body += [f"    Guard* g = find((void*){names[0]}, \"{name}\");",
                     f"    if (!g || !{ptr}) return {err};",
                     "    if (g->state == S_FATAL) {",
                     f"        say(g, 3, \"{name} refused: the instance failed earlier (see the log); free it\");",
                     f"        return {err};",
                     "    }"]
            if short in _STATE_FUNCS:
                allowed, _ = _STATE_FUNCS[short]
                body += [f"    if (g->state != {allowed}) {{",
                         f"        say(g, 3, \"{name} refused in state '%s' (allowed: '%s'){' : the episode is running; call reset to start again' if short == 'ExitInitializationMode' else ''}\", "
                         f"STATE_NAME[g->state], STATE_NAME[{allowed}]);",
                         f"        return {err};",
                         "    }"]
            if (fmi == 2 and short == "SetupExperiment") or (fmi == 3 and short == "EnterInitializationMode"):
                body += ["    if (startTime != 0.0) {",
                         f"        say(g, 3, \"{name}: start time %.17g s refused: a navsim episode starts at t = 0 "
                         "(the FMU's time counts ticks from the episode start)\", startTime);",
                         f"        return {err};",
                         "    }"]
            if short == "Terminate":
                body += ["    if (g->state == S_TERM) return 0;  /* a second terminate does nothing */",
                         "    if (g->state != S_RUN && g->state != S_INIT) {",
                         f"        say(g, 3, \"{name} refused in state '%s'\", STATE_NAME[g->state]);",
                         f"        return {err};",
                         "    }"]
            if short in _SETTERS:
                vr_arg = names[1]
                n_arg = names[2]
                body += ["    if (g->state != S_INST && g->state != S_INIT)",
                         f"        for (size_t i = 0; i < {n_arg}; i++)",
                         f"            if (is_parameter({vr_arg}[i])) {{",
                         f"                say(g, 3, \"{name}: value reference %u is a parameter; parameters cannot be set "
                         "after initialisation (call reset first)\", {vr_arg}[i]);".replace("{vr_arg}", vr_arg),
                         f"                return {err};",
                         "            }"]
            if short == "ExitInitializationMode":
                body.append("    refused = 0;")
            body.append(f"    {ret} r = {ptr}({fwd});")
            if short == "ExitInitializationMode":  # a bad parameter: error status, still in initialisation mode
                body += ["    if (refused) {", "        refused = 0;", f"        say(g, 3, \"{name} refused: %s\", refused_msg);",
                         f"        return {err};", "    }"]
            body.append("    if (r == 4) g->state = S_FATAL;")
            trans = {"EnterInitializationMode": "S_INIT", "ExitInitializationMode": "S_RUN", "Terminate": "S_TERM",
                     "Reset": "S_INST"}.get(short)
            if trans:
                body.append(f"    else if (r <= 1) g->state = {trans};")
            body += ["    return r;", "}"]
        lines.append("\n".join(body) + "\n")
    return "\n".join(lines)


def compile_guard(fmi: int, parameter_vrs: list[int], identifier: str, out_dir: Path) -> Path | None:
    """Compile the guard as ``out_dir/<identifier>.so`` (forwarding to
    ``<identifier>_pythonfmu.so``); None when gcc or the headers are missing (RuntimeError
    with the compiler's message when compiling fails: a bug)."""
    gcc = shutil.which("gcc")
    headers = headers_dir()
    if gcc is None or headers is None:
        return None
    src = out_dir / f"{identifier}_guard.c"
    src.write_text(guard_source(fmi, parameter_vrs, headers, f"{identifier}_pythonfmu.so"), encoding="utf-8")
    lib = out_dir / f"{identifier}.so"
    done = subprocess.run([gcc, "-O2", "-shared", "-fPIC", "-Wall", "-Werror", f"-I{headers}", str(src), "-o", str(lib), "-ldl",
                           "-lpthread"], capture_output=True, text=True)
    if done.returncode or not lib.exists():
        raise RuntimeError(f"compiling the FMU's C guard failed: {done.stderr[-2000:]}")
    return lib
