//! Minimal InvenSense MPU-6000 driver over `embedded-hal-async` SPI (no maintained async driver
//! crate covers the MPU-6000's SPI mode, so this is the small register-level one the firmware needs).
//!
//! Configuration: gyro ±2000 °/s (16.4 LSB/(°/s)), accel ±16 g (2048 LSB/g), DLPF 188 Hz, 1 kHz
//! output rate, data-ready interrupt on INT (active high, push-pull, cleared on any read). One
//! read is a 14-byte burst from ACCEL_XOUT_H. The SPI clock must be ≤ 1 MHz for register writes
//! (the board keeps it there; reads tolerate 20 MHz).
//!
//! Axes: the sensor frame is the chip's (x, y, z up out of the package). [`AxisMap`] maps it to
//! body FRD; the board module sets it for the chip's mounting.

use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::spi::{Operation, SpiDevice};
use parapet_core::Vec3;

use crate::app::autopilot::ImuSample;

/// Register addresses.
mod reg {
    pub const SMPLRT_DIV: u8 = 0x19;
    pub const CONFIG: u8 = 0x1A;
    pub const GYRO_CONFIG: u8 = 0x1B;
    pub const ACCEL_CONFIG: u8 = 0x1C;
    pub const INT_PIN_CFG: u8 = 0x37;
    pub const INT_ENABLE: u8 = 0x38;
    pub const ACCEL_XOUT_H: u8 = 0x3B;
    pub const SIGNAL_PATH_RESET: u8 = 0x68;
    pub const USER_CTRL: u8 = 0x6A;
    pub const PWR_MGMT_1: u8 = 0x6B;
    pub const WHO_AM_I: u8 = 0x75;
}

/// WHO_AM_I value of the MPU-6000.
pub const WHO_AM_I_VALUE: u8 = 0x68;
/// Gyro scale at ±2000 °/s, rad/s per LSB.
pub const GYRO_RAD_PER_LSB: f32 = (core::f32::consts::PI / 180.0) / 16.4;
/// Accel scale at ±16 g, m/s² per LSB.
pub const ACCEL_MS2_PER_LSB: f32 = parapet_core::frame::GRAVITY / 2048.0;

// SMPLRT_DIV 0 with the DLPF on samples at 1 kHz: the core's inner-loop rate.
const _: () = assert!(parapet_core::wire::rates::INNER_RATE_HZ == 1000);

/// Register writes of the initialisation, in order (after the device reset).
pub const INIT_SEQUENCE: [(u8, u8); 8] = [
    (reg::PWR_MGMT_1, 0x03),   // clock: PLL with gyro Z reference
    (reg::USER_CTRL, 0x10),    // I2C interface off (SPI only)
    (reg::SMPLRT_DIV, 0x00),   // 1 kHz / (1 + 0)
    (reg::CONFIG, 0x01),       // DLPF 188 Hz (gyro output rate 1 kHz)
    (reg::GYRO_CONFIG, 0x18),  // ±2000 °/s
    (reg::ACCEL_CONFIG, 0x18), // ±16 g
    (reg::INT_PIN_CFG, 0x10),  // INT active high, push-pull, pulse, clear on any read
    (reg::INT_ENABLE, 0x01),   // data-ready interrupt
];

/// Sensor-to-FRD axis map: FRD axis `i` = `sign[i]` × sensor axis `axis[i]`. Must be a proper
/// rotation (a signed permutation with determinant +1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AxisMap {
    /// Source sensor axis for F, R, D.
    pub axis: [u8; 3],
    /// Sign for F, R, D (+1 / −1).
    pub sign: [i8; 3],
}

impl AxisMap {
    /// Chip x forward, y left, z up (pin 1 front-left, package face up): FRD = (x, −y, −z).
    pub const X_FORWARD_Z_UP: Self = Self { axis: [0, 1, 2], sign: [1, -1, -1] };

    /// Applies the map to a sensor-frame vector.
    pub fn apply(&self, v: [f32; 3]) -> Vec3 {
        let c = |i: usize| v[usize::from(self.axis[i] % 3)] * f32::from(self.sign[i]);
        Vec3::new(c(0), c(1), c(2))
    }
}

/// Driver errors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImuError {
    /// SPI transfer failed.
    Bus,
    /// WHO_AM_I did not match (wrong chip, wiring, or SPI mode).
    WrongDevice(u8),
}

/// Converts a 14-byte burst (accel xyz, temperature, gyro xyz; big-endian i16) into a sample.
pub fn convert_burst(raw: &[u8; 14], map: &AxisMap) -> ImuSample {
    let w = |i: usize| f32::from(i16::from_be_bytes([raw[i], raw[i + 1]]));
    let acc = [w(0) * ACCEL_MS2_PER_LSB, w(2) * ACCEL_MS2_PER_LSB, w(4) * ACCEL_MS2_PER_LSB];
    let gyr = [w(8) * GYRO_RAD_PER_LSB, w(10) * GYRO_RAD_PER_LSB, w(12) * GYRO_RAD_PER_LSB];
    ImuSample { gyro: map.apply(gyr), accel: map.apply(acc) }
}

/// MPU-6000 on an SPI device (chip select handled by the `SpiDevice`).
pub struct Mpu6000<S> {
    spi: S,
    map: AxisMap,
}

impl<S: SpiDevice> Mpu6000<S> {
    /// Driver for the chip behind `spi`, mounted as `map`.
    pub fn new(spi: S, map: AxisMap) -> Self {
        Self { spi, map }
    }

    /// The SPI device (e.g. to change the bus clock after initialisation).
    pub fn bus_mut(&mut self) -> &mut S {
        &mut self.spi
    }

    async fn write(&mut self, r: u8, v: u8) -> Result<(), ImuError> {
        self.spi.write(&[r & 0x7F, v]).await.map_err(|_| ImuError::Bus)
    }

    async fn read_reg(&mut self, r: u8) -> Result<u8, ImuError> {
        let mut b = [0u8; 1];
        self.spi
            .transaction(&mut [Operation::Write(&[r | 0x80]), Operation::Read(&mut b)])
            .await
            .map_err(|_| ImuError::Bus)?;
        Ok(b[0])
    }

    /// Resets and configures the chip (≈ 250 ms).
    pub async fn init(&mut self, delay: &mut impl DelayNs) -> Result<(), ImuError> {
        self.write(reg::PWR_MGMT_1, 0x80).await?;
        delay.delay_ms(100).await;
        self.write(reg::SIGNAL_PATH_RESET, 0x07).await?;
        delay.delay_ms(100).await;
        let who = self.read_reg(reg::WHO_AM_I).await?;
        if who != WHO_AM_I_VALUE {
            return Err(ImuError::WrongDevice(who));
        }
        for (r, v) in INIT_SEQUENCE {
            self.write(r, v).await?;
            delay.delay_us(15).await;
        }
        Ok(())
    }

    /// Reads one sample (accel, gyro) in body FRD.
    pub async fn read(&mut self) -> Result<ImuSample, ImuError> {
        let mut raw = [0u8; 14];
        self.spi
            .transaction(&mut [Operation::Write(&[reg::ACCEL_XOUT_H | 0x80]), Operation::Read(&mut raw)])
            .await
            .map_err(|_| ImuError::Bus)?;
        Ok(convert_burst(&raw, &self.map))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    /// Fake chip: records writes, answers WHO_AM_I and a fixed burst.
    struct FakeChip {
        writes: Vec<(u8, u8)>,
        who: u8,
        burst: [u8; 14],
    }

    impl embedded_hal_async::spi::ErrorType for FakeChip {
        type Error = core::convert::Infallible;
    }

    impl SpiDevice for FakeChip {
        async fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), Self::Error> {
            let mut addr = None;
            for op in ops.iter_mut() {
                match op {
                    Operation::Write(w) if w.len() == 2 => self.writes.push((w[0], w[1])),
                    Operation::Write(w) => addr = w.first().copied(),
                    Operation::Read(r) => match addr {
                        Some(a) if a == reg::WHO_AM_I | 0x80 => r[0] = self.who,
                        Some(a) if a == reg::ACCEL_XOUT_H | 0x80 => r.copy_from_slice(&self.burst),
                        _ => r.fill(0),
                    },
                    _ => {}
                }
            }
            Ok(())
        }
    }

    struct NoDelay;
    impl DelayNs for NoDelay {
        async fn delay_ns(&mut self, _ns: u32) {}
    }

    #[test]
    fn init_writes_the_configuration_and_checks_the_id() {
        let chip = FakeChip { writes: Vec::new(), who: WHO_AM_I_VALUE, burst: [0; 14] };
        let mut imu = Mpu6000::new(chip, AxisMap::X_FORWARD_Z_UP);
        assert_eq!(embassy_futures::block_on(imu.init(&mut NoDelay)), Ok(()));
        let w = &imu.spi.writes;
        assert_eq!(w[0], (reg::PWR_MGMT_1, 0x80));
        assert_eq!(&w[2..], &INIT_SEQUENCE[..]);
        let chip = FakeChip { writes: Vec::new(), who: 0x70, burst: [0; 14] };
        let mut imu = Mpu6000::new(chip, AxisMap::X_FORWARD_Z_UP);
        assert_eq!(embassy_futures::block_on(imu.init(&mut NoDelay)), Err(ImuError::WrongDevice(0x70)));
    }

    #[test]
    fn burst_is_scaled_and_rotated_to_frd() {
        // Level at rest: accel z = +1 g (2048 LSB); gyro x = +16.4 LSB (1 °/s), z = −164 (−10 °/s).
        let mut burst = [0u8; 14];
        burst[4..6].copy_from_slice(&2048i16.to_be_bytes());
        burst[8..10].copy_from_slice(&16i16.to_be_bytes());
        burst[12..14].copy_from_slice(&(-164i16).to_be_bytes());
        let chip = FakeChip { writes: Vec::new(), who: WHO_AM_I_VALUE, burst };
        let mut imu = Mpu6000::new(chip, AxisMap::X_FORWARD_Z_UP);
        let s = embassy_futures::block_on(imu.read()).expect("fake bus");
        assert!((s.accel - Vec3::new(0.0, 0.0, -9.81)).norm() < 1e-4, "{s:?}");
        let deg = core::f32::consts::PI / 180.0;
        assert!((s.gyro.x - 16.0 / 16.4 * deg).abs() < 1e-6);
        assert!((s.gyro.z - 10.0 * deg).abs() < 1e-6);
    }
}
