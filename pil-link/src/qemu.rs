//! Starts a firmware image in QEMU (mps2-an386, Cortex-M4F; or netduinoplus2, STM32F405:
//! [`Machine`]) with its link UART on a Unix socket the harness listens on (loopback only,
//! no network) or on a pseudo-terminal the harness opens as a serial device
//! ([`LinkPort`]), and its semihosting output (the defmt log) in a file. Needs `std`.

use crate::host::{Stream, open_serial};
use std::fs::File;
use std::io;
use std::os::unix::net::UnixListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

/// Where QEMU puts the firmware's UART0 for the harness.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LinkPort {
    /// A Unix socket QEMU connects to.
    #[default]
    Socket,
    /// A pseudo-terminal QEMU creates, which the harness opens as a serial device (termios,
    /// read timeouts): the code path of a board's `/dev/ttyACM0`.
    Pty,
}

impl core::str::FromStr for LinkPort {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "socket" => Ok(Self::Socket),
            "pty" => Ok(Self::Pty),
            other => Err(format!("link port {other:?}: one of socket, pty")),
        }
    }
}

/// The QEMU machine, and so which of its serial ports is the link.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Machine {
    /// mps2-an386 (Cortex-M4F): the link on UART0, QEMU's first serial port.
    #[default]
    Mps2An386,
    /// netduinoplus2 (STM32F405): the link on USART2, QEMU's second serial port. QEMU 7.2
    /// models its USARTs but not its clock controller, TIM1/6/7 nor its flash controller.
    Netduinoplus2,
}

impl Machine {
    /// QEMU's name of the machine.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::Mps2An386 => "mps2-an386",
            Self::Netduinoplus2 => "netduinoplus2",
        }
    }

    /// Serial ports ahead of the link's (`-serial null` each).
    const fn ports_before_link(self) -> usize {
        match self {
            Self::Mps2An386 => 0,
            Self::Netduinoplus2 => 1,
        }
    }
}

/// How to start QEMU.
#[derive(Clone, Debug)]
pub struct QemuOptions {
    /// The QEMU binary (`qemu-system-arm`).
    pub qemu: PathBuf,
    /// The firmware ELF (the `pil` image).
    pub elf: PathBuf,
    /// Where QEMU's stdout goes: the firmware's defmt-over-semihosting log (binary).
    pub log: PathBuf,
    /// How long QEMU may take to connect to the socket (or to name its pseudo-terminal).
    pub connect_timeout: Duration,
    /// Where the link UART goes.
    pub port: LinkPort,
    /// The machine.
    pub machine: Machine,
}

/// Why QEMU could not be started or connected.
#[derive(Debug)]
pub enum QemuError {
    /// The QEMU binary is missing.
    NotInstalled {
        /// What was run.
        qemu: PathBuf,
    },
    /// The ELF does not exist.
    NoImage {
        /// Path given.
        elf: PathBuf,
    },
    /// QEMU exited before connecting (bad arguments, bad image).
    ExitedEarly {
        /// Its exit status.
        status: ExitStatus,
        /// Its stderr.
        stderr: String,
    },
    /// QEMU did not connect in time.
    ConnectTimeout {
        /// Time waited.
        waited: Duration,
    },
    /// An I/O error (socket, log file, process).
    Io(io::Error),
}

impl core::fmt::Display for QemuError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::NotInstalled { qemu } => write!(
                f,
                "{} not found: install QEMU (Debian/Ubuntu: apt-get install qemu-system-arm)",
                qemu.display()
            ),
            Self::NoImage { elf } => write!(f, "firmware image {} does not exist", elf.display()),
            Self::ExitedEarly { status, stderr } => {
                write!(
                    f,
                    "QEMU exited before connecting ({status}): {}",
                    stderr.trim()
                )
            }
            Self::ConnectTimeout { waited } => {
                write!(
                    f,
                    "QEMU did not connect to the PIL socket within {waited:?}"
                )
            }
            Self::Io(e) => write!(f, "QEMU I/O: {e}"),
        }
    }
}

impl std::error::Error for QemuError {}

impl From<io::Error> for QemuError {
    fn from(e: io::Error) -> Self {
        Self::Io(e)
    }
}

/// What QEMU writes on its stdout, before anything else, when it puts a UART on a
/// pseudo-terminal: this, the device's path, and " (label serialN)". The firmware's defmt
/// log follows on the same stream ([`log_bytes`] leaves the notice out).
pub const PTY_NOTICE: &str = "char device redirected to ";

/// The firmware's log in QEMU's stdout `bytes`, without the pseudo-terminal notice line.
#[must_use]
pub fn log_bytes(bytes: &[u8]) -> &[u8] {
    if bytes.starts_with(PTY_NOTICE.as_bytes()) {
        bytes
            .iter()
            .position(|b| *b == b'\n')
            .and_then(|i| bytes.get(i + 1..))
            .unwrap_or(&[])
    } else {
        bytes
    }
}

/// A running QEMU with the PIL image. Dropping it kills QEMU and removes the socket.
pub struct Qemu {
    child: Child,
    dir: PathBuf,
    stderr_path: PathBuf,
    stdout_path: PathBuf,
}

static INSTANCE: AtomicU32 = AtomicU32::new(0);

impl Qemu {
    /// Starts QEMU and waits for it to connect; returns it and the UART0 stream.
    pub fn spawn(opts: &QemuOptions) -> Result<(Self, Stream), QemuError> {
        if !opts.elf.is_file() {
            return Err(QemuError::NoImage {
                elf: opts.elf.clone(),
            });
        }
        let n = INSTANCE.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("stiffdrive-pil-{}-{n}", std::process::id()));
        std::fs::create_dir_all(&dir)?;
        let sock = dir.join("uart0.sock");
        let listener = match opts.port {
            LinkPort::Socket => {
                let l = UnixListener::bind(&sock)?;
                l.set_nonblocking(true)?;
                Some(l)
            }
            LinkPort::Pty => None,
        };
        let mut serial: Vec<String> = Vec::new();
        for _ in 0..opts.machine.ports_before_link() {
            serial.extend(["-serial".into(), "null".into()]);
        }
        serial.extend::<Vec<String>>(match opts.port {
            LinkPort::Socket => vec![
                "-chardev".into(),
                format!("socket,id=pil,path={}", sock.display()),
                "-serial".into(),
                "chardev:pil".into(),
            ],
            LinkPort::Pty => vec!["-serial".into(), "pty".into()],
        });
        let cpu: &[&str] = match opts.machine {
            Machine::Mps2An386 => &["-cpu", "cortex-m4"],
            Machine::Netduinoplus2 => &[],
        };
        let stderr_path = dir.join("qemu.stderr");
        let spawned = Command::new(&opts.qemu)
            .args(["-machine", opts.machine.name()])
            .args(cpu)
            .args(["-nographic", "-monitor", "none"])
            .args(["-semihosting-config", "enable=on,target=native"])
            .args(&serial)
            .arg("-kernel")
            .arg(&opts.elf)
            .stdin(Stdio::null())
            .stdout(File::create(&opts.log)?)
            .stderr(File::create(&stderr_path)?)
            .spawn();
        let child = match spawned {
            Ok(c) => c,
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                let _ = std::fs::remove_dir_all(&dir);
                return Err(QemuError::NotInstalled {
                    qemu: opts.qemu.clone(),
                });
            }
            Err(e) => return Err(e.into()),
        };
        let mut qemu = Self {
            child,
            dir,
            stderr_path,
            stdout_path: opts.log.clone(),
        };
        let start = Instant::now();
        loop {
            if let Some(stream) = qemu.connected(listener.as_ref())? {
                return Ok((qemu, stream));
            }
            if let Some(status) = qemu.child.try_wait()? {
                return Err(QemuError::ExitedEarly {
                    status,
                    stderr: qemu.stderr(),
                });
            }
            if start.elapsed() > opts.connect_timeout {
                return Err(QemuError::ConnectTimeout {
                    waited: start.elapsed(),
                });
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// The UART0 stream once there is one: QEMU connected to the socket `listener`, or
    /// (without one) named the pseudo-terminal it made, on the first line of its stdout
    /// ([`PTY_NOTICE`]), which is then opened as a serial device.
    fn connected(&self, listener: Option<&UnixListener>) -> Result<Option<Stream>, QemuError> {
        if let Some(l) = listener {
            return match l.accept() {
                Ok((stream, _)) => {
                    stream.set_nonblocking(false)?;
                    Ok(Some(Stream::Socket(stream)))
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => Ok(None),
                Err(e) => Err(e.into()),
            };
        }
        let stdout = std::fs::read(&self.stdout_path)?;
        let Some(path) = stdout
            .strip_prefix(PTY_NOTICE.as_bytes())
            .and_then(|rest| rest.split(|b| *b == b' ' || *b == b'\n').next())
            .and_then(|p| std::str::from_utf8(p).ok())
            .filter(|p| !p.is_empty())
        else {
            return Ok(None);
        };
        // The firmware talks only after the harness's Hello, so nothing is lost before.
        Ok(Some(open_serial(Path::new(path), 115_200)?))
    }

    /// Waits up to `timeout` for QEMU to exit (the firmware exits through semihosting after
    /// `Stop`); kills it otherwise. Returns the exit status if it exited by itself.
    pub fn finish(&mut self, timeout: Duration) -> Option<ExitStatus> {
        let start = Instant::now();
        while start.elapsed() < timeout {
            if let Ok(Some(status)) = self.child.try_wait() {
                return Some(status);
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
        None
    }

    /// What QEMU wrote to stderr so far.
    pub fn stderr(&self) -> String {
        std::fs::read_to_string(&self.stderr_path).unwrap_or_default()
    }

    /// The temporary directory holding the socket.
    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

impl Drop for Qemu {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}
