//! The onboard log of the STM32 boards' binaries (`src/bin/fc/`): the log task's state
//! ([`BoardLog`]: the card store, the ULog logger, the MAVLink log download), the queue the
//! outer task samples into and the LOG_* request/reply channels the link task uses (see
//! `src/bin/fc/mod.rs`'s module doc for the tasks and priorities). With the `onboard-log` feature;
//! without it the same functions are no-ops (no log in the image).
//!
//! A module of the binary, not of the library: it owns statics of the board image. May
//! import `parapet_firmware` (app, board, link, log) and `parapet_core`.

#[cfg(not(feature = "onboard-log"))]
use parapet_firmware::{
    app::autopilot::MotorCommand, link::frame_parser::RawFrame, link::framing::FrameWriter,
};

#[cfg(feature = "onboard-log")]
pub use on::*;

/// No log in this build: no frame is a log request.
#[cfg(not(feature = "onboard-log"))]
pub fn forward(_f: &RawFrame<'_>) -> bool {
    false
}

/// No log in this build: nothing to send.
#[cfg(not(feature = "onboard-log"))]
pub async fn send_replies(
    _tx: &mut embassy_stm32::usart::UartTx<'static, embassy_stm32::mode::Async>,
    _writer: &mut FrameWriter,
) {
}

#[cfg(not(feature = "onboard-log"))]
pub fn motors(_cmd: &MotorCommand) {}

#[cfg(feature = "onboard-log")]
mod on {
    use core::sync::atomic::{AtomicU32, Ordering};

    use crate::Board;
    use embassy_futures::select::{select3, Either3};
    use embassy_stm32::mode::Async;
    use embassy_stm32::usart::UartTx;
    use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
    use embassy_sync::channel::Channel;
    use embassy_time::Timer;
    use parapet_core::controller::ControllerParams;
    use parapet_firmware::app::autopilot::MotorCommand;
    use parapet_firmware::app::cascade::OuterStage;
    use parapet_firmware::board::stm32::{FlightBoard, LogCardDevice};
    use parapet_firmware::link::dialect::{MavSeverity, STATUSTEXT_DATA};
    use parapet_firmware::link::frame_parser::RawFrame;
    use parapet_firmware::link::framing::{FrameWriter, VEHICLE_SYSTEM_ID};
    use parapet_firmware::link::outbound::Outbound;
    use parapet_firmware::log::card::CardStore;
    use parapet_firmware::log::logger::{FlightLogger, LogSample, DEFAULT_PERIOD_US};
    use parapet_firmware::log::transfer::{LogReply, LogTransfer, REPLIES_PER_POLL};
    use static_cell::StaticCell;

    /// The board's log card.
    type LogCard = <Board as FlightBoard>::LogCard;

    /// Log samples in flight from the outer task to the log task (25 Hz: the log task,
    /// alone in thread mode, takes each within a pass unless the card or a flash write
    /// stalls it; then later samples are dropped and counted).
    const LOG_QUEUE_LEN: usize = 1;
    /// LOG_* requests in flight from the link task to the log task (a full queue drops
    /// the request, counted; the ground station repeats it).
    const REQUEST_DEPTH: usize = 2;
    /// Bytes of a LOG_* request payload kept (LOG_REQUEST_DATA, the longest, has 12).
    const REQUEST_PAYLOAD: usize = 12;
    /// Bytes of one batch of log frames: a STATUSTEXT (66) and [`REPLIES_PER_POLL`]
    /// LOG_DATA frames (MAVLink 2 header 10 + payload 97 + CRC 2; LOG_ENTRY is 26).
    const LOG_TX_BATCH: usize = 66 + REPLIES_PER_POLL * 109;
    /// Log task period while a download streams, ms (≤ REPLIES_PER_POLL per pass).
    const LOG_PASS_MS: u64 = 5;
    /// Outer task → log task: log samples.
    static LOG_QUEUE: Channel<CriticalSectionRawMutex, LogSample, LOG_QUEUE_LEN> = Channel::new();
    /// Link task → log task: LOG_* requests.
    static REQUESTS: Channel<CriticalSectionRawMutex, LogRequest, REQUEST_DEPTH> = Channel::new();
    /// Log task → link task: replies and the card's STATUSTEXTs, in order.
    static OUT: Channel<CriticalSectionRawMutex, LogOut, REPLIES_PER_POLL> = Channel::new();
    /// Log samples dropped because [`LOG_QUEUE`] was full.
    pub static LOG_DROPPED: AtomicU32 = AtomicU32::new(0);
    /// LOG_* requests dropped because [`REQUESTS`] was full.
    pub static REQUESTS_DROPPED: AtomicU32 = AtomicU32::new(0);
    /// Inner task → outer task: the last motor throttles (f32 bits; for the log only).
    static MOTOR_OUT: [AtomicU32; 4] = [const { AtomicU32::new(0) }; 4];
    static STORE: StaticCell<CardStore<LogCard>> = StaticCell::new();
    static PARAMS: StaticCell<ControllerParams> = StaticCell::new();
    /// The log task's state (handed over by reference: module doc of `src/bin/fc/mod.rs`).
    pub static LOG: StaticCell<BoardLog> = StaticCell::new();

    /// A LOG_* request copied out of the link task's framer.
    struct LogRequest {
        msg_id: u32,
        sys_id: u8,
        comp_id: u8,
        seq: u8,
        len: u8,
        payload: [u8; REQUEST_PAYLOAD],
    }

    /// What the log task hands the link task to send.
    enum LogOut {
        Reply(LogReply),
        Text(&'static str),
    }

    /// Inner task: the motor command just sent (4 relaxed stores).
    pub fn motors(cmd: &MotorCommand) {
        for (o, t) in MOTOR_OUT.iter().zip(cmd.throttle) {
            o.store(t.to_bits(), Ordering::Relaxed);
        }
    }

    /// Outer task, after its step: one sample every `DEFAULT_PERIOD_US` into the
    /// queue (copied, never a wait; dropped and counted when full).
    pub fn sample(now: u64, stage: &OuterStage, next_us: &mut u64) {
        if now < *next_us {
            return;
        }
        *next_us = now.saturating_add(DEFAULT_PERIOD_US);
        let motors = MOTOR_OUT.each_ref().map(|m| f32::from_bits(m.load(Ordering::Relaxed)));
        let sample = LogSample { t_us: now, snapshot: stage.snapshot(), motors };
        if LOG_QUEUE.try_send(sample).is_err() {
            LOG_DROPPED.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Link task: a received frame; `true` if it is a LOG_* request (handed to the log
    /// task, never a wait: dropped and counted when the queue is full).
    pub fn forward(f: &RawFrame<'_>) -> bool {
        if !LogTransfer::handles(f.msg_id) {
            return false;
        }
        let mut payload = [0u8; REQUEST_PAYLOAD];
        let n = f.payload.len().min(REQUEST_PAYLOAD);
        payload[..n].copy_from_slice(&f.payload[..n]);
        let r = LogRequest {
            msg_id: f.msg_id,
            sys_id: f.sys_id,
            comp_id: f.comp_id,
            seq: f.seq,
            len: n as u8,
            payload,
        };
        if REQUESTS.try_send(r).is_err() {
            REQUESTS_DROPPED.fetch_add(1, Ordering::Relaxed);
        }
        true
    }

    /// Link task: the log task's frames, encoded with the link's writer (one sequence)
    /// into one byte batch and written in one DMA transfer.
    pub async fn send_replies(tx: &mut UartTx<'static, Async>, writer: &mut FrameWriter) {
        let mut batch: heapless::Vec<u8, LOG_TX_BATCH> = heapless::Vec::new();
        while let Ok(o) = OUT.try_receive() {
            let raw = match o {
                LogOut::Reply(r) => r.encode(writer),
                LogOut::Text(t) => match status(t).encode(writer) {
                    parapet_firmware::link::outbound::Encoded::V2(r) => r,
                    parapet_firmware::link::outbound::Encoded::V1(_) => continue,
                },
            };
            // OUT holds ≤ REPLIES_PER_POLL items, the batch their longest frames.
            let _ = batch.extend_from_slice(raw.raw_bytes());
        }
        if !batch.is_empty() {
            let _ = tx.write(&batch).await;
        }
    }

    /// A STATUSTEXT of the log (card formatted, card fault).
    fn status(text: &str) -> Outbound {
        let mut buf = [0u8; 50];
        for (d, s) in buf.iter_mut().zip(text.bytes()) {
            *d = s;
        }
        let severity = MavSeverity::MAV_SEVERITY_WARNING;
        Outbound::StatusText(STATUSTEXT_DATA { severity, text: buf.into(), ..Default::default() })
    }

    /// The log task's state: logger, card store, download.
    pub struct BoardLog {
        store: &'static mut CardStore<LogCard>,
        params: &'static ControllerParams,
        logger: FlightLogger,
        transfer: LogTransfer,
    }

    impl BoardLog {
        /// On `card`, naming the boot parameters `params` in each log.
        pub fn new(card: LogCard, params: ControllerParams) -> Self {
            let params: &'static ControllerParams = PARAMS.init(params);
            Self {
                store: STORE.init(CardStore::new(card)),
                params,
                logger: FlightLogger::new(DEFAULT_PERIOD_US, params, Board::NAME),
                transfer: LogTransfer::new(VEHICLE_SYSTEM_ID),
            }
        }

        /// The log task: mounts the card (blocking: init at 400 kHz, then the fast
        /// clock; a formatted card is said once), then per pass (on a sample, a request
        /// or every [`LOG_PASS_MS`]): the queued samples (≤ `LOG_QUEUE_LEN` record
        /// sets, ≤ 1 card block each plus a directory write every 16 blocks), the queued
        /// requests, a fault STATUSTEXT (once), and at most `REPLIES_PER_POLL`
        /// LOG_ENTRY/LOG_DATA when the link task has taken the previous ones.
        pub async fn run(&mut self) -> ! {
            let mounted = self.store.mount();
            self.store.device().go_fast();
            if let Some(t) = mounted.ok().and_then(|m| m.text()) {
                OUT.send(LogOut::Text(t)).await;
            }
            let params = self.params;
            loop {
                let first =
                    select3(LOG_QUEUE.receive(), REQUESTS.receive(), Timer::after_millis(LOG_PASS_MS)).await;
                match first {
                    Either3::First(s) => {
                        self.logger.on_sample(&s, &mut *self.store, |n| parapet_core::params::get(params, n))
                    }
                    Either3::Second(r) => self.request(&r),
                    Either3::Third(()) => {}
                }
                while let Ok(s) = LOG_QUEUE.try_receive() {
                    self.logger.on_sample(&s, &mut *self.store, |n| parapet_core::params::get(params, n));
                }
                while let Ok(r) = REQUESTS.try_receive() {
                    self.request(&r);
                }
                if let Some(t) = self.store.take_fault() {
                    OUT.send(LogOut::Text(t)).await;
                }
                if OUT.is_empty() {
                    // OUT has room for every reply one poll emits.
                    self.transfer.poll(&mut *self.store, &mut |r| {
                        let _ = OUT.try_send(LogOut::Reply(r));
                    });
                }
            }
        }

        fn request(&mut self, r: &LogRequest) {
            let f = RawFrame {
                msg_id: r.msg_id,
                sys_id: r.sys_id,
                comp_id: r.comp_id,
                seq: r.seq,
                payload: r.payload.get(..usize::from(r.len)).unwrap_or(&[]),
            };
            self.transfer.on_frame(&f, &mut *self.store);
        }
    }
}
