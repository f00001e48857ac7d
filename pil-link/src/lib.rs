//! pil-link: the processor-in-the-loop link between `hil-harness` and the firmware running
//! in QEMU. Each tick the harness sends the sampled sensors, the firmware answers with its
//! commands; frames are versioned and checksummed so a lost, corrupted or late frame is seen
//! by both sides.
#![no_std]
