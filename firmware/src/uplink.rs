//! Uplink: encoded `aim-wire` frames go out on USART3 (the ST-LINK virtual COM port) by DMA.
//!
//! Producers push encoded frames into [`UPLINK_QUEUE`]; when it is full the oldest frame is
//! dropped and counted (a fresh DoA is worth more than a stale one, and the sequence gap tells
//! the host). The uplink task copies each frame into a transmit buffer in AXI SRAM (DMA cannot
//! read DTCM, where the queue lives) and writes it with DMA.
use embassy_stm32::mode::Async;
use embassy_stm32::peripherals::{DMA1_CH1, PD8, USART3};
use embassy_stm32::usart::{self, UartTx};
use embassy_stm32::Peri;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::{Channel, TrySendError};

use crate::config::{UPLINK_BAUD, UPLINK_QUEUE_FRAMES};
use crate::stats::{bump, COUNTERS};
use crate::Irqs;

/// Largest encoded frame (COBS-framed, delimiter included), bytes.
pub const MAX_FRAME_BYTES: usize = aim_wire::MAX_ENCODED_LEN;

/// One encoded frame, delimiter included.
pub type EncodedFrame = heapless::Vec<u8, MAX_FRAME_BYTES>;

/// A bounded queue of encoded frames that drops its oldest frame when full.
pub struct UplinkQueue {
    frames: Channel<CriticalSectionRawMutex, EncodedFrame, UPLINK_QUEUE_FRAMES>,
}

impl UplinkQueue {
    /// An empty queue.
    pub const fn new() -> Self {
        Self { frames: Channel::new() }
    }

    /// Queues `frame`; if the queue is full, drops the oldest frame first and counts it in
    /// `frames_dropped`. Never waits.
    pub fn push_drop_oldest(&self, frame: EncodedFrame) {
        let mut frame = frame;
        // Two rounds suffice with one consumer; a bound keeps this loop finite regardless.
        for _ in 0..UPLINK_QUEUE_FRAMES {
            match self.frames.try_send(frame) {
                Ok(()) => return,
                Err(TrySendError::Full(returned)) => {
                    frame = returned;
                    if self.frames.try_receive().is_ok() {
                        bump(&COUNTERS.frames_dropped);
                    }
                }
            }
        }
        bump(&COUNTERS.frames_dropped);
    }

    /// Frames waiting.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Whether no frame is waiting.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Waits for the next frame.
    pub async fn pop(&self) -> EncodedFrame {
        self.frames.receive().await
    }
}

impl Default for UplinkQueue {
    fn default() -> Self {
        Self::new()
    }
}

/// The firmware's uplink queue.
pub static UPLINK_QUEUE: UplinkQueue = UplinkQueue::new();

/// Creates the USART3 transmitter (PD8, DMA1 stream 1) at [`UPLINK_BAUD`], 8N1.
pub fn uplink_uart(
    usart: Peri<'static, USART3>,
    tx: Peri<'static, PD8>,
    dma: Peri<'static, DMA1_CH1>,
) -> Result<UartTx<'static, Async>, usart::ConfigError> {
    let mut config = usart::Config::default();
    config.baudrate = UPLINK_BAUD;
    UartTx::new(usart, tx, dma, Irqs, config)
}

/// Sends queued frames forever. A transmit error is counted and the next frame is sent.
#[embassy_executor::task]
pub async fn uplink_task(mut uart: UartTx<'static, Async>) {
    let tx_buffer = crate::axisram_buffer!(u8, MAX_FRAME_BYTES);
    loop {
        let frame = UPLINK_QUEUE.pop().await;
        let bytes = &mut tx_buffer[..frame.len()];
        bytes.copy_from_slice(&frame);
        match uart.write(bytes).await {
            Ok(()) => bump(&COUNTERS.frames_sent),
            Err(error) => {
                bump(&COUNTERS.uart_errors);
                defmt::warn!("uplink: USART3 {}", error);
            }
        }
    }
}
