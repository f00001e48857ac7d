//! Starts the firmware's PIL image in QEMU (mps2-an386, Cortex-M4F) with UART0 on a Unix
//! socket the harness listens on (loopback only, no network), and its semihosting output
//! (the defmt log) in a file. Needs `std`.

use std::fs::File;
use std::io;
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

/// How to start QEMU.
#[derive(Clone, Debug)]
pub struct QemuOptions {
    /// The QEMU binary (`qemu-system-arm`).
    pub qemu: PathBuf,
    /// The firmware ELF (the `pil` image).
    pub elf: PathBuf,
    /// Where QEMU's stdout goes: the firmware's defmt-over-semihosting log (binary).
    pub log: PathBuf,
    /// How long QEMU may take to connect to the socket.
    pub connect_timeout: Duration,
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

/// A running QEMU with the PIL image. Dropping it kills QEMU and removes the socket.
pub struct Qemu {
    child: Child,
    dir: PathBuf,
    stderr_path: PathBuf,
}

static INSTANCE: AtomicU32 = AtomicU32::new(0);

impl Qemu {
    /// Starts QEMU and waits for it to connect; returns it and the UART0 stream.
    pub fn spawn(opts: &QemuOptions) -> Result<(Self, UnixStream), QemuError> {
        if !opts.elf.is_file() {
            return Err(QemuError::NoImage {
                elf: opts.elf.clone(),
            });
        }
        let n = INSTANCE.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("stiffdrive-pil-{}-{n}", std::process::id()));
        std::fs::create_dir_all(&dir)?;
        let sock = dir.join("uart0.sock");
        let listener = UnixListener::bind(&sock)?;
        listener.set_nonblocking(true)?;
        let stderr_path = dir.join("qemu.stderr");
        let spawned = Command::new(&opts.qemu)
            .args(["-machine", "mps2-an386", "-cpu", "cortex-m4"])
            .args(["-nographic", "-monitor", "none"])
            .args(["-semihosting-config", "enable=on,target=native"])
            .arg("-chardev")
            .arg(format!("socket,id=pil,path={}", sock.display()))
            .args(["-serial", "chardev:pil"])
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
        };
        let start = Instant::now();
        loop {
            match listener.accept() {
                Ok((stream, _)) => {
                    stream.set_nonblocking(false)?;
                    return Ok((qemu, stream));
                }
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {}
                Err(e) => return Err(e.into()),
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
