//! Per-kernel GPU times from timestamp queries, for [`crate::GpuBackend::enable_profiling`].
//!
//! While profiling, every dispatch gets its own compute pass whose beginning and end write
//! a timestamp into a query set. At the end of each command buffer (or when the query set
//! is full) the timestamps are resolved and copied, still on the device, to the end of a
//! log buffer. The log is mapped and summed per kernel only when the caller asks for the
//! times, or when it is full (every few thousand dispatches); both are blocking readbacks.

use std::sync::atomic::{AtomicU64, Ordering};

/// Timestamps per query set (two per dispatch).
const QUERIES: u32 = wgpu::QUERY_SET_MAX_QUERIES;
/// Timestamps the log holds before it is read back (at least one command buffer's worth).
const LOG_QUERIES: u32 = 16384;
/// Bytes per resolved timestamp.
const QUERY_BYTES: u64 = wgpu::QUERY_SIZE as u64;

/// GPU time spent in one kernel while profiling was on.
#[derive(Debug, Clone, PartialEq)]
pub struct KernelTime {
    /// Kernel name (as in [`crate::kernels::Kernel::name`]).
    pub name: &'static str,
    /// Dispatches timed.
    pub dispatches: u64,
    /// Sum of their GPU times, ms.
    pub total_ms: f64,
    /// Mean GPU time per dispatch, ms (0 without dispatches).
    pub mean_ms: f64,
}

/// Query set, resolve buffer, log and the totals so far.
#[derive(Debug)]
pub(crate) struct Profiler {
    /// Whether new dispatches are timed.
    pub on: bool,
    queries: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    log: wgpu::Buffer,
    /// Capacity of the log, timestamps.
    log_queries: u32,
    /// Timestamps written to the query set and not yet resolved.
    used: u32,
    /// Timestamps in the log.
    logged: u32,
    /// Kernel of every timed dispatch not yet summed, in order.
    order: Vec<u16>,
    /// Nanoseconds per timestamp tick.
    period_ns: f64,
    /// Per kernel: dispatches and nanoseconds summed so far.
    totals: Vec<(u64, f64)>,
    /// Why a log readback failed, reported by the next [`Profiler::times`].
    failed: Option<String>,
}

impl Profiler {
    /// A profiler for `kernels` kernels whose command buffers record at most
    /// `max_dispatches` dispatches each.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        kernels: usize,
        max_dispatches: u64,
    ) -> Profiler {
        let log_queries = LOG_QUERIES.max((2 * max_dispatches).min(u32::MAX as u64) as u32);
        Profiler {
            on: false,
            queries: device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("kernel timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: QUERIES,
            }),
            resolve: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamp resolve"),
                size: QUERIES as u64 * QUERY_BYTES,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            log: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamp log"),
                size: log_queries as u64 * QUERY_BYTES,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            log_queries,
            used: 0,
            logged: 0,
            order: Vec::new(),
            period_ns: queue.get_timestamp_period() as f64,
            totals: vec![(0, 0.0); kernels],
            failed: None,
        }
    }

    /// Makes room in the log for `dispatches` more (at most the `max_dispatches` of
    /// [`Profiler::new`]), reading it back first when it is too full.
    pub fn reserve(&mut self, device: &wgpu::Device, dispatches: u64, readbacks: &AtomicU64) {
        if self.logged as u64 + 2 * dispatches > self.log_queries as u64 {
            self.drain(device, readbacks);
        }
    }

    /// The timestamp writes of the next dispatch, of kernel `kernel`; resolves the query set
    /// into the log first when it is full.
    pub fn next(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        kernel: usize,
    ) -> wgpu::ComputePassTimestampWrites<'_> {
        if self.used + 2 > QUERIES {
            self.flush(encoder);
        }
        let first = self.used;
        self.used += 2;
        self.order.push(kernel as u16);
        wgpu::ComputePassTimestampWrites {
            query_set: &self.queries,
            beginning_of_pass_write_index: Some(first),
            end_of_pass_write_index: Some(first + 1),
        }
    }

    /// Resolves the timestamps written so far and appends them to the log (recorded in
    /// `encoder`, after its dispatches).
    pub fn flush(&mut self, encoder: &mut wgpu::CommandEncoder) {
        if self.used == 0 {
            return;
        }
        encoder.resolve_query_set(&self.queries, 0..self.used, &self.resolve, 0);
        encoder.copy_buffer_to_buffer(
            &self.resolve,
            0,
            &self.log,
            self.logged as u64 * QUERY_BYTES,
            self.used as u64 * QUERY_BYTES,
        );
        self.logged += self.used;
        self.used = 0;
    }

    /// Reads the log back (waiting for the submitted work) and adds it to the totals.
    pub fn drain(&mut self, device: &wgpu::Device, readbacks: &AtomicU64) {
        let logged = self.logged;
        self.logged = 0;
        let order = std::mem::take(&mut self.order);
        if logged == 0 {
            return;
        }
        let bytes = logged as u64 * QUERY_BYTES;
        let (totals, period) = (&mut self.totals, self.period_ns);
        let read = map_read(
            device,
            "timestamp log",
            &self.log,
            bytes,
            readbacks,
            |data| {
                let stamps: Vec<u64> = data
                    .chunks_exact(QUERY_BYTES as usize)
                    .map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")))
                    .collect();
                for (pair, &kernel) in stamps.chunks_exact(2).zip(&order) {
                    let t = &mut totals[kernel as usize];
                    t.0 += 1;
                    t.1 += pair[1].saturating_sub(pair[0]) as f64 * period;
                }
            },
        );
        if let Err(e) = read {
            self.failed.get_or_insert(e);
        }
    }

    /// Per-kernel times summed so far (reads the log back first), named by `names`; an
    /// error if a readback of the log failed since the last reset.
    pub fn times(
        &mut self,
        device: &wgpu::Device,
        names: &[&'static str],
        readbacks: &AtomicU64,
    ) -> Result<Vec<KernelTime>, String> {
        self.drain(device, readbacks);
        if let Some(e) = &self.failed {
            return Err(e.clone());
        }
        Ok(names
            .iter()
            .zip(&self.totals)
            .map(|(&name, &(dispatches, ns))| KernelTime {
                name,
                dispatches,
                total_ms: ns * 1e-6,
                mean_ms: if dispatches == 0 {
                    0.0
                } else {
                    ns * 1e-6 / dispatches as f64
                },
            })
            .collect())
    }

    /// Forgets the totals and the timestamps not yet summed.
    pub fn reset(&mut self) {
        self.totals.fill((0, 0.0));
        self.logged = 0;
        self.order.clear();
        self.failed = None;
    }
}

/// Maps the first `bytes` of `buffer` (a `MAP_READ` buffer, named `what` in errors), waits for it, hands the bytes
/// to `f` and unmaps it; counts one readback.
pub(crate) fn map_read(
    device: &wgpu::Device,
    what: &str,
    buffer: &wgpu::Buffer,
    bytes: u64,
    readbacks: &AtomicU64,
    f: impl FnOnce(&[u8]),
) -> Result<(), String> {
    let slice = buffer.slice(..bytes);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    readbacks.fetch_add(1, Ordering::Relaxed);
    let _ = device.poll(wgpu::PollType::wait_indefinitely());
    match rx.recv() {
        Ok(Ok(())) => {}
        other => return Err(format!("mapping the {what} buffer failed: {other:?}")),
    }
    {
        let view = slice
            .get_mapped_range()
            .map_err(|e| format!("reading the mapped buffer failed: {e}"))?;
        f(&view);
    }
    buffer.unmap();
    Ok(())
}
