//! PX4's mission id: a CRC32 over the items, as `mavlink_mission.cpp`
//! computes it while an upload arrives (`crc32_for_mission_item`) and puts
//! in MISSION_ACK `opaque_id`, MISSION_COUNT and MISSION_CURRENT
//! `mission_id` / `fence_id` / `rally_points_id`.
//!
//! Per item, in sequence order, the bytes of
//! `{frame: u8, command: u16, autocontinue: u8, params: [f32; 7]}` (packed,
//! little-endian; params 5 and 6 are MISSION_ITEM_INT's `x`, `y` integers,
//! their bits as PX4's union reads them) are fed to NuttX's `crc32part`:
//! the reflected polynomial 0xEDB88320, `crc = table[(crc ^ b) & 0xff] ^ (crc >> 8)`,
//! starting from 0, with no final inversion. An empty plan has id 0.

use super::MissionItem;

/// The reflected CRC-32 table (polynomial 0xEDB88320).
const TABLE: [u32; 256] = {
    let mut t = [0u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
            k += 1;
        }
        t[i] = c;
        i += 1;
    }
    t
};

/// NuttX `crc32part`: continue `crc` over `bytes`.
#[must_use]
pub fn crc32part(bytes: &[u8], mut crc: u32) -> u32 {
    for &b in bytes {
        crc = TABLE[((crc ^ u32::from(b)) & 0xff) as usize] ^ (crc >> 8);
    }
    crc
}

/// The 32 bytes PX4 feeds to the CRC for one item.
#[must_use]
pub fn item_bytes(item: &MissionItem) -> [u8; 32] {
    let mut b = [0u8; 32];
    b[0] = item.frame;
    b[1..3].copy_from_slice(&item.command.to_le_bytes());
    b[3] = u8::from(item.autocontinue);
    for (k, p) in item.params.iter().enumerate() {
        b[4 + 4 * k..8 + 4 * k].copy_from_slice(&p.to_le_bytes());
    }
    b[20..24].copy_from_slice(&item.x_int().to_le_bytes());
    b[24..28].copy_from_slice(&item.y_int().to_le_bytes());
    b[28..32].copy_from_slice(&item.z.to_le_bytes());
    b
}

/// The id of a plan: [`crc32part`] over every item's [`item_bytes`], from 0.
#[must_use]
pub fn plan_id(items: &[MissionItem]) -> u32 {
    items.iter().fold(0, |crc, it| crc32part(&item_bytes(it), crc))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32part_with_the_standard_framing_is_the_standard_crc32() {
        // CRC-32 (IEEE) of "123456789" is 0xCBF43926 = !crc32part(data, !0)
        assert_eq!(!crc32part(b"123456789", !0), 0xCBF4_3926);
    }

    #[test]
    fn the_id_depends_on_every_field_and_the_order() {
        let a = MissionItem {
            frame: 3,
            command: 16,
            autocontinue: true,
            params: [0.0, 1.0, 0.0, f32::NAN],
            x: 47.397_742_0,
            y: 8.545_594_0,
            z: 10.0,
        };
        let mut b = a;
        b.z = 11.0;
        assert_eq!(plan_id(&[]), 0);
        assert_ne!(plan_id(&[a]), plan_id(&[b]));
        assert_ne!(plan_id(&[a, b]), plan_id(&[b, a]));
        assert_eq!(
            plan_id(&[a, b]),
            crc32part(&item_bytes(&b), crc32part(&item_bytes(&a), 0))
        );
    }
}
