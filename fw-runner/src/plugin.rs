//! The QEMU TCG plugin of the cycle estimate: this crate's library is also built as a
//! shared object (`libfw_runner.so`), which `qemu-system-arm -plugin` loads.
//!
//! At each translated block it decodes every instruction from QEMU's disassembly
//! ([`crate::cycles::decode`]) and registers a callback on its execution, and one on each
//! load's memory access; the callbacks feed a [`Tracker`], and every window the tracker
//! finishes is appended to the output file as one line ([`crate::cycles::window_line`]),
//! flushed at once, so the file is whole however QEMU exits.
//!
//! Arguments (`-plugin libfw_runner.so,out=FILE,arm_current=ADDR[,arm_velocity=ADDR]
//! [,preempt=ADDR][,next_group=ADDR]`): the output file and the mark functions' addresses (see
//! [`crate::cycles`]).
//!
//! The plugin API (QEMU 7.2, plugin API version 1) is looked up with `dlsym` in QEMU's
//! own symbols when QEMU installs the plugin, so no binary that links this library needs
//! QEMU's symbols.
//!
//! This is the one module of the crate with `unsafe`: the C interface of QEMU's plugins.

#![allow(unsafe_code)]

use crate::cycles::{window_line, Insn, Marks, Tracker};
use std::ffi::{c_char, c_int, c_uint, c_void, CStr};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::sync::{Mutex, OnceLock, PoisonError};

/// The plugin API version this plugin is written against (QEMU 7.2's).
#[allow(non_upper_case_globals)]
#[no_mangle]
pub static qemu_plugin_version: c_int = 1;

type PluginId = u64;
type TbTransCb = extern "C" fn(PluginId, *mut c_void);
type InsnExecCb = extern "C" fn(c_uint, *mut c_void);
type MemCb = extern "C" fn(c_uint, u32, u64, *mut c_void);

/// `QEMU_PLUGIN_CB_NO_REGS`.
const CB_NO_REGS: c_int = 0;
/// `QEMU_PLUGIN_MEM_RW`: QEMU 7.2 makes no callback for `QEMU_PLUGIN_MEM_R` (1) alone;
/// the callback is registered on load instructions only, so it sees their reads.
const MEM_RW: c_int = 3;

/// The functions of QEMU's plugin API this plugin calls.
struct Api {
    register_tb_trans: extern "C" fn(PluginId, TbTransCb),
    tb_n_insns: extern "C" fn(*const c_void) -> usize,
    tb_get_insn: extern "C" fn(*const c_void, usize) -> *mut c_void,
    insn_vaddr: extern "C" fn(*const c_void) -> u64,
    insn_size: extern "C" fn(*const c_void) -> usize,
    insn_disas: extern "C" fn(*const c_void) -> *mut c_char,
    register_insn_exec: extern "C" fn(*mut c_void, InsnExecCb, c_int, *mut c_void),
    register_mem: extern "C" fn(*mut c_void, MemCb, c_int, c_int, *mut c_void),
    g_free: Option<extern "C" fn(*mut c_void)>,
}

#[link(name = "dl")]
extern "C" {
    fn dlsym(handle: *mut c_void, symbol: *const c_char) -> *mut c_void;
}

/// The address of `name` among the symbols already loaded (QEMU's own), if any.
fn lookup(name: &CStr) -> Option<*mut c_void> {
    // SAFETY: dlsym with RTLD_DEFAULT (a null handle on glibc) and a NUL-terminated name
    // only searches the loaded objects' symbol tables.
    let p = unsafe { dlsym(std::ptr::null_mut(), name.as_ptr()) };
    (!p.is_null()).then_some(p)
}

macro_rules! api_fn {
    ($name:literal, $ty:ty) => {{
        match lookup($name) {
            // SAFETY: the symbol is QEMU's plugin API function of that name, whose C
            // signature (qemu-plugin.h of QEMU 7.2) is `$ty`.
            Some(p) => unsafe { std::mem::transmute::<*mut c_void, $ty>(p) },
            None => return None,
        }
    }};
}

impl Api {
    fn load() -> Option<Self> {
        Some(Self {
            register_tb_trans: api_fn!(
                c"qemu_plugin_register_vcpu_tb_trans_cb",
                extern "C" fn(PluginId, TbTransCb)
            ),
            tb_n_insns: api_fn!(
                c"qemu_plugin_tb_n_insns",
                extern "C" fn(*const c_void) -> usize
            ),
            tb_get_insn: api_fn!(
                c"qemu_plugin_tb_get_insn",
                extern "C" fn(*const c_void, usize) -> *mut c_void
            ),
            insn_vaddr: api_fn!(
                c"qemu_plugin_insn_vaddr",
                extern "C" fn(*const c_void) -> u64
            ),
            insn_size: api_fn!(
                c"qemu_plugin_insn_size",
                extern "C" fn(*const c_void) -> usize
            ),
            insn_disas: api_fn!(
                c"qemu_plugin_insn_disas",
                extern "C" fn(*const c_void) -> *mut c_char
            ),
            register_insn_exec: api_fn!(
                c"qemu_plugin_register_vcpu_insn_exec_cb",
                extern "C" fn(*mut c_void, InsnExecCb, c_int, *mut c_void)
            ),
            register_mem: api_fn!(
                c"qemu_plugin_register_vcpu_mem_cb",
                extern "C" fn(*mut c_void, MemCb, c_int, c_int, *mut c_void)
            ),
            g_free: lookup(c"g_free").map(|p| {
                // SAFETY: glib's `void g_free(gpointer)`, which QEMU links.
                unsafe { std::mem::transmute::<*mut c_void, extern "C" fn(*mut c_void)>(p) }
            }),
        })
    }
}

/// The plugin's state: the tracker and the output file.
struct State {
    tracker: Tracker,
    out: BufWriter<File>,
    /// Windows already written.
    written: usize,
    dropped: u32,
    /// Group marks already written.
    groups: u32,
}

static API: OnceLock<Api> = OnceLock::new();
static STATE: Mutex<Option<State>> = Mutex::new(None);

/// One instruction's record, handed to its callback (leaked: one per translation).
struct Rec {
    pc: u64,
    insn: Insn,
}

fn with_state(f: impl FnOnce(&mut State)) {
    let mut guard = STATE.lock().unwrap_or_else(PoisonError::into_inner);
    if let Some(state) = guard.as_mut() {
        f(state);
    }
}

/// Writes the windows the tracker finished since the last call.
fn flush(state: &mut State) {
    let new = state
        .tracker
        .windows
        .get(state.written..)
        .unwrap_or_default();
    if new.is_empty()
        && state.tracker.dropped == state.dropped
        && state.tracker.groups == state.groups
    {
        return;
    }
    for (which, w) in new {
        let _ = writeln!(state.out, "{}", window_line(*which, w));
    }
    if state.tracker.dropped != state.dropped {
        let _ = writeln!(
            state.out,
            "dropped {}",
            state.tracker.dropped - state.dropped
        );
        state.dropped = state.tracker.dropped;
    }
    // The windows so far belong to the groups before the mark.
    for _ in state.groups..state.tracker.groups {
        let _ = writeln!(state.out, "group");
    }
    state.groups = state.tracker.groups;
    state.written = state.tracker.windows.len();
    let _ = state.out.flush();
}

extern "C" fn on_exec(_vcpu: c_uint, userdata: *mut c_void) {
    // SAFETY: `userdata` is the leaked `Rec` registered with this callback in `on_tb`.
    let rec = unsafe { &*(userdata as *const Rec) };
    with_state(|s| {
        s.tracker.exec(rec.pc, rec.insn);
        if s.tracker.dropped != s.dropped || s.tracker.groups != s.groups {
            flush(s);
        }
    });
}

extern "C" fn on_load(_vcpu: c_uint, _info: u32, vaddr: u64, _userdata: *mut c_void) {
    with_state(|s| {
        let before = s.tracker.windows.len();
        s.tracker.load(vaddr);
        if s.tracker.windows.len() != before {
            flush(s);
        }
    });
}

extern "C" fn on_tb(_id: PluginId, tb: *mut c_void) {
    let Some(api) = API.get() else { return };
    let n = (api.tb_n_insns)(tb);
    for i in 0..n {
        let insn = (api.tb_get_insn)(tb, i);
        if insn.is_null() {
            continue;
        }
        let pc = (api.insn_vaddr)(insn);
        let size = (api.insn_size)(insn);
        let text = (api.insn_disas)(insn);
        let disas = if text.is_null() {
            String::new()
        } else {
            // SAFETY: QEMU returns a NUL-terminated string it allocated with glib.
            let s = unsafe { CStr::from_ptr(text) }
                .to_string_lossy()
                .into_owned();
            if let Some(free) = api.g_free {
                free(text.cast());
            }
            s
        };
        let decoded = crate::cycles::decode(&disas, u32::try_from(size).unwrap_or(4));
        let load = decoded.is_single_load();
        let rec = Box::into_raw(Box::new(Rec { pc, insn: decoded })).cast::<c_void>();
        (api.register_insn_exec)(insn, on_exec, CB_NO_REGS, rec);
        if load {
            (api.register_mem)(insn, on_load, CB_NO_REGS, MEM_RW, std::ptr::null_mut());
        }
    }
}

/// The plugin's arguments.
fn parse_args(args: &[String]) -> Option<(String, Marks)> {
    let mut out = None;
    let mut marks = Marks::default();
    for a in args {
        let (k, v) = a.split_once('=')?;
        let addr = || u64::from_str_radix(v.trim_start_matches("0x"), 16).ok();
        match k {
            "out" => out = Some(v.to_string()),
            "arm_current" => marks.arm_current = Some(addr()?),
            "arm_velocity" => marks.arm_velocity = Some(addr()?),
            "preempt" => marks.preempt = Some(addr()?),
            "next_group" => marks.next_group = Some(addr()?),
            _ => return None,
        }
    }
    Some((out?, marks))
}

/// QEMU's entry point of the plugin.
///
/// # Safety
///
/// Called by QEMU only, with `argv` holding `argc` NUL-terminated strings.
#[no_mangle]
pub unsafe extern "C" fn qemu_plugin_install(
    id: PluginId,
    _info: *const c_void,
    argc: c_int,
    argv: *const *const c_char,
) -> c_int {
    let args: Vec<String> = (0..usize::try_from(argc).unwrap_or(0))
        .filter_map(|i| {
            // SAFETY: QEMU passes `argc` NUL-terminated strings in `argv`.
            let p = unsafe { *argv.add(i) };
            // SAFETY: `p` is one of them, not null.
            (!p.is_null()).then(|| unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned())
        })
        .collect();
    let Some((out, marks)) = parse_args(&args) else {
        eprintln!("fw-runner cycle plugin: bad arguments {args:?}");
        return -1;
    };
    let Some(api) = Api::load() else {
        eprintln!("fw-runner cycle plugin: QEMU's plugin API was not found");
        return -1;
    };
    let file = match File::create(&out) {
        Ok(f) => f,
        Err(e) => {
            eprintln!("fw-runner cycle plugin: cannot create {out}: {e}");
            return -1;
        }
    };
    *STATE.lock().unwrap_or_else(PoisonError::into_inner) = Some(State {
        tracker: Tracker::new(marks),
        out: BufWriter::new(file),
        written: 0,
        dropped: 0,
        groups: 0,
    });
    let register = api.register_tb_trans;
    let _ = API.set(api);
    register(id, on_tb);
    0
}
