//! The run file's PDO mapping resolved to offsets in the process image,
//! and one mapped value read and written there.

use exo_config::{EthercatSettings, PdoEntry, PdoRole, PdoSettings};

use super::EthercatError;

/// One mapped value: where it sits in the process image, its width, its scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Field {
    pub(super) offset: usize,
    pub(super) bits: u8,
    pub(super) scale: f64,
}

impl Field {
    pub(super) fn of(pdo: &PdoSettings, role: PdoRole) -> Option<Field> {
        pdo.find(role).map(|(offset, e): (usize, PdoEntry)| Field {
            offset,
            bits: e.bits,
            scale: e.scale.unwrap_or(1.0),
        })
    }

    /// The value as a signed integer of its width (little-endian).
    pub(super) fn read(&self, image: &[u8]) -> i64 {
        let b = |i: usize| image.get(self.offset + i).copied().unwrap_or(0);
        match self.bits {
            8 => i64::from(b(0) as i8),
            16 => i64::from(i16::from_le_bytes([b(0), b(1)])),
            _ => i64::from(i32::from_le_bytes([b(0), b(1), b(2), b(3)])),
        }
    }

    /// Writes `value`, saturated to the width's range.
    pub(super) fn write(&self, image: &mut [u8], value: i64) {
        let n = usize::from(self.bits / 8);
        let (lo, hi) = self.range();
        let bytes = value.clamp(lo, hi).to_le_bytes();
        if let Some(dst) = image.get_mut(self.offset..self.offset + n) {
            dst.copy_from_slice(&bytes[..n]);
        }
    }

    pub(super) fn range(&self) -> (i64, i64) {
        match self.bits {
            8 => (i64::from(i8::MIN), i64::from(i8::MAX)),
            16 => (i64::from(i16::MIN), i64::from(i16::MAX)),
            _ => (i64::from(i32::MIN), i64::from(i32::MAX)),
        }
    }
}

/// The run file's mapping resolved to offsets.
#[derive(Debug, Clone, Copy)]
pub(super) struct Map {
    pub(super) controlword: Field,
    pub(super) mode: Option<Field>,
    pub(super) torque: Field,
    pub(super) statusword: Field,
    pub(super) position: Field,
    pub(super) velocity: Option<Field>,
    pub(super) torque_actual: Option<Field>,
    pub(super) error_code: Option<Field>,
    pub(super) sea: Option<Field>,
    pub(super) cuff: [Option<Field>; 6],
    pub(super) in_bytes: usize,
    pub(super) out_bytes: usize,
}

impl Map {
    pub(super) fn new(s: &EthercatSettings) -> Result<Map, EthercatError> {
        let need = |pdo: &PdoSettings, role, key: &'static str| {
            Field::of(pdo, role).ok_or(EthercatError::MissingRole { pdo: key, role })
        };
        let (rx, tx) = (&s.rx_pdo, &s.tx_pdo);
        let rxk = "bus.ethercat.rx_pdo";
        let txk = "bus.ethercat.tx_pdo";
        Ok(Map {
            controlword: need(rx, PdoRole::Controlword, rxk)?,
            mode: Field::of(rx, PdoRole::ModeOfOperation),
            torque: need(rx, PdoRole::TargetTorque, rxk)?,
            statusword: need(tx, PdoRole::Statusword, txk)?,
            position: need(tx, PdoRole::PositionActual, txk)?,
            velocity: Field::of(tx, PdoRole::VelocityActual),
            torque_actual: Field::of(tx, PdoRole::TorqueActual),
            error_code: Field::of(tx, PdoRole::ErrorCode),
            sea: Field::of(tx, PdoRole::SeaDeflection),
            cuff: [
                PdoRole::CuffFx,
                PdoRole::CuffFy,
                PdoRole::CuffFz,
                PdoRole::CuffTx,
                PdoRole::CuffTy,
                PdoRole::CuffTz,
            ]
            .map(|r| Field::of(tx, r)),
            in_bytes: tx.bytes(),
            out_bytes: rx.bytes(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_read_and_write_little_endian_signed_and_saturate() {
        let mut image = [0u8; 8];
        let f16 = Field {
            offset: 2,
            bits: 16,
            scale: 1.0,
        };
        f16.write(&mut image, -2);
        assert_eq!(image[2..4], [0xFE, 0xFF]);
        assert_eq!(f16.read(&image), -2);
        f16.write(&mut image, 100_000);
        assert_eq!(f16.read(&image), 32767, "saturated, not wrapped");
        let f32_ = Field {
            offset: 4,
            bits: 32,
            scale: 1.0,
        };
        f32_.write(&mut image, 0x0102_0304);
        assert_eq!(image[4..8], [4, 3, 2, 1]);
        let f8 = Field {
            offset: 0,
            bits: 8,
            scale: 1.0,
        };
        f8.write(&mut image, -200);
        assert_eq!(f8.read(&image), -128);
        assert_eq!(image[2..4], [0xFF, 0x7F], "neighbours untouched");
    }
}
