//! A read-only memory map of a whole file: the bag is paged in by the kernel as it is
//! read, never copied whole into memory.
//!
//! A reader that has finished with a part of the file hands it back
//! ([`Mapped::release`]), so that the pages it read do not stay counted in the process's
//! memory for the rest of a long bag. The map is private and read-only; as with every memory map, a file truncated by another
//! process while it is mapped makes the reads past its new end fault.

use std::fs::File;
use std::os::fd::AsRawFd;

/// A file mapped into memory (empty files map to an empty slice).
#[derive(Debug)]
pub struct Mapped {
    ptr: *mut libc::c_void,
    len: usize,
    /// Bytes from the start already handed back to the kernel (page-aligned).
    released: std::cell::Cell<usize>,
}

impl Mapped {
    /// Maps `file` whole, for sequential reading.
    pub fn new(file: &File) -> std::io::Result<Self> {
        let len = usize::try_from(file.metadata()?.len())
            .map_err(|_| std::io::Error::other("file too large to map"))?;
        if len == 0 {
            return Ok(Mapped {
                ptr: std::ptr::null_mut(),
                len,
                released: std::cell::Cell::new(0),
            });
        }
        // SAFETY: a fresh private read-only mapping of an open file descriptor; the result
        // is checked against MAP_FAILED before use.
        let ptr = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                len,
                libc::PROT_READ,
                libc::MAP_PRIVATE,
                file.as_raw_fd(),
                0,
            )
        };
        if ptr == libc::MAP_FAILED {
            return Err(std::io::Error::last_os_error());
        }
        // SAFETY: advice on the mapping just made; failure only loses the read-ahead hint.
        unsafe { libc::madvise(ptr, len, libc::MADV_SEQUENTIAL) };
        Ok(Mapped {
            ptr,
            len,
            released: std::cell::Cell::new(0),
        })
    }

    /// Hands the pages of `..upto` back to the kernel: they are read again from the file
    /// (or the page cache) if touched later, so this changes no byte the map reads.
    pub fn release(&self, upto: usize) {
        const PAGE: usize = 4096;
        let end = upto.min(self.len) / PAGE * PAGE;
        if upto < self.released.get() {
            self.released.set(0); // a new pass from the start
        }
        let start = self.released.get();
        if end <= start + (1 << 20) {
            return; // at least 1 MiB at a time
        }
        // SAFETY: `start..end` lies inside the mapping and is page-aligned (the mapping
        // starts on a page); MADV_DONTNEED on a private read-only file mapping only drops
        // the pages, which are read again from the file when touched.
        unsafe {
            libc::madvise(
                (self.ptr as *mut u8).add(start) as *mut libc::c_void,
                end - start,
                libc::MADV_DONTNEED,
            )
        };
        self.released.set(end);
    }

    /// The file's bytes.
    pub fn bytes(&self) -> &[u8] {
        if self.len == 0 {
            return &[];
        }
        // SAFETY: `ptr` maps `len` readable bytes for as long as `self` lives.
        unsafe { std::slice::from_raw_parts(self.ptr as *const u8, self.len) }
    }
}

impl Drop for Mapped {
    fn drop(&mut self) {
        if self.len > 0 {
            // SAFETY: unmaps exactly the mapping made in `new`, once.
            unsafe { libc::munmap(self.ptr, self.len) };
        }
    }
}
