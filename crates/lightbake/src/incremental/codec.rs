//! The bake cache's bytes: a header (magic, format version, the baker's version, the
//! payload's length and checksum) and a payload of little-endian fields. The reader checks
//! every length against the bytes left before it allocates, so a truncated, damaged or
//! hostile file gives an error, never a panic or an allocation it does not hold.

/// The file's first bytes.
pub(super) const MAGIC: &[u8; 8] = b"LBCACHE\0";

/// The payload's layout. A cache of another format version is not read.
pub(super) const FORMAT: u32 = 6;

/// The checksum of the payload: FNV-1a's step (xor, then multiply by its 64-bit prime)
/// taken a little-endian 64-bit word at a time, the last word padded with zeros, then the
/// length. Each step is a bijection of the state, so a payload that differs in one word
/// always differs in its checksum; a word at a time it reads a partial checkpoint's tens
/// of megabytes about eight times faster than byte by byte.
pub(crate) fn checksum(bytes: &[u8]) -> u64 {
    const PRIME: u64 = 0x0100_0000_01b3;
    let step = |h: u64, w: u64| (h ^ w).wrapping_mul(PRIME);
    let mut chunks = bytes.chunks_exact(8);
    let mut h = (&mut chunks).fold(0xcbf2_9ce4_8422_2325, |h, c| {
        step(h, u64::from_le_bytes(c.try_into().expect("eight bytes")))
    });
    let rest = chunks.remainder();
    if !rest.is_empty() {
        let mut last = [0u8; 8];
        last[..rest.len()].copy_from_slice(rest);
        h = step(h, u64::from_le_bytes(last));
    }
    step(h, bytes.len() as u64)
}

/// Builds a payload.
#[derive(Default)]
pub(crate) struct Writer {
    out: Vec<u8>,
}

impl Writer {
    pub(crate) fn u32(&mut self, v: u32) {
        self.out.extend_from_slice(&v.to_le_bytes());
    }

    pub(crate) fn u64(&mut self, v: u64) {
        self.out.extend_from_slice(&v.to_le_bytes());
    }

    pub(crate) fn f32(&mut self, v: f32) {
        self.out.extend_from_slice(&v.to_le_bytes());
    }

    pub(crate) fn bool(&mut self, v: bool) {
        self.out.push(u8::from(v));
    }

    pub(crate) fn len(&mut self, n: usize) {
        self.u64(n as u64);
    }

    pub(crate) fn bytes(&mut self, b: &[u8]) {
        self.len(b.len());
        self.out.extend_from_slice(b);
    }

    pub(crate) fn str(&mut self, s: &str) {
        self.bytes(s.as_bytes());
    }

    pub(crate) fn u32s(&mut self, v: &[u32]) {
        self.len(v.len());
        for x in v {
            self.u32(*x);
        }
    }

    pub(crate) fn u64s(&mut self, v: &[u64]) {
        self.len(v.len());
        for x in v {
            self.u64(*x);
        }
    }

    pub(crate) fn f32s(&mut self, v: &[f32]) {
        self.len(v.len());
        for x in v {
            self.f32(*x);
        }
    }

    /// The payload alone (a part that another payload holds as [`Self::bytes`]).
    pub(crate) fn into_bytes(self) -> Vec<u8> {
        self.out
    }

    /// The file: header and payload. `version` is the baker's.
    pub(super) fn finish(self, version: &str) -> Vec<u8> {
        let mut file = Vec::with_capacity(self.out.len() + 64);
        file.extend_from_slice(MAGIC);
        file.extend_from_slice(&FORMAT.to_le_bytes());
        file.extend_from_slice(&(version.len() as u32).to_le_bytes());
        file.extend_from_slice(version.as_bytes());
        file.extend_from_slice(&(self.out.len() as u64).to_le_bytes());
        file.extend_from_slice(&checksum(&self.out).to_le_bytes());
        file.extend_from_slice(&self.out);
        file
    }
}

/// Why a cache file could not be read.
pub(crate) type Bad = String;

/// Reads a payload, checking every length against the bytes left.
#[derive(Debug)]
pub(crate) struct Reader<'a> {
    rest: &'a [u8],
}

impl<'a> Reader<'a> {
    /// A reader of a payload without a header: a part that another, checksummed payload
    /// held as bytes.
    pub(crate) fn part(bytes: &'a [u8]) -> Self {
        Reader { rest: bytes }
    }

    /// The payload of `file` when its header is this format's, `version` is the baker's that
    /// wrote it, and the checksum holds.
    pub(super) fn open(file: &'a [u8], version: &str) -> Result<Self, Bad> {
        let mut r = Reader { rest: file };
        if r.take(8)? != MAGIC {
            return Err("it is not a lightbake cache".into());
        }
        let format = r.u32()?;
        if format != FORMAT {
            return Err(format!("it has format {format}, this baker reads {FORMAT}"));
        }
        let n = r.u32()? as usize;
        let written_by = String::from_utf8_lossy(r.take(n)?).into_owned();
        if written_by != version {
            return Err(format!(
                "it was written by lightbake {written_by}, this is {version}"
            ));
        }
        let len = r.u64()?;
        let sum = r.u64()?;
        if len != r.rest.len() as u64 {
            return Err(format!(
                "its payload is {} bytes, its header says {len} (truncated or damaged)",
                r.rest.len()
            ));
        }
        if checksum(r.rest) != sum {
            return Err("its checksum does not match (damaged)".into());
        }
        Ok(r)
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], Bad> {
        if n > self.rest.len() {
            return Err(format!("it ends {} bytes early", n - self.rest.len()));
        }
        let (head, tail) = self.rest.split_at(n);
        self.rest = tail;
        Ok(head)
    }

    pub(crate) fn u32(&mut self) -> Result<u32, Bad> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    pub(crate) fn u64(&mut self) -> Result<u64, Bad> {
        let b = self.take(8)?;
        let mut a = [0; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }

    pub(crate) fn f32(&mut self) -> Result<f32, Bad> {
        Ok(f32::from_bits(self.u32()?))
    }

    pub(crate) fn bool(&mut self) -> Result<bool, Bad> {
        match self.take(1)?[0] {
            0 => Ok(false),
            1 => Ok(true),
            b => Err(format!("a flag holds {b}")),
        }
    }

    /// A count of elements of `size` bytes each, refused when they would not fit the bytes
    /// left.
    pub(crate) fn len(&mut self, size: usize) -> Result<usize, Bad> {
        let n = self.u64()?;
        let fits = (n as u128) * (size.max(1) as u128) <= self.rest.len() as u128;
        if !fits {
            return Err(format!(
                "it names {n} elements of {size} bytes where {} bytes are left",
                self.rest.len()
            ));
        }
        Ok(n as usize)
    }

    pub(crate) fn bytes(&mut self) -> Result<&'a [u8], Bad> {
        let n = self.len(1)?;
        self.take(n)
    }

    pub(crate) fn str(&mut self) -> Result<String, Bad> {
        String::from_utf8(self.bytes()?.to_vec()).map_err(|_| "a name is not UTF-8".into())
    }

    pub(crate) fn u32s(&mut self) -> Result<Vec<u32>, Bad> {
        let n = self.len(4)?;
        (0..n).map(|_| self.u32()).collect()
    }

    pub(crate) fn u64s(&mut self) -> Result<Vec<u64>, Bad> {
        let n = self.len(8)?;
        (0..n).map(|_| self.u64()).collect()
    }

    pub(crate) fn f32s(&mut self) -> Result<Vec<f32>, Bad> {
        let n = self.len(4)?;
        (0..n).map(|_| self.f32()).collect()
    }

    /// Ends the payload: every byte read.
    pub(crate) fn end(self) -> Result<(), Bad> {
        if self.rest.is_empty() {
            Ok(())
        } else {
            Err(format!("{} bytes follow its end", self.rest.len()))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Vec<u8> {
        let mut w = Writer::default();
        w.u32(7);
        w.str("lamp");
        w.f32s(&[1.0, 2.5]);
        w.u64s(&[u64::MAX]);
        w.bool(true);
        w.finish("1.2.3")
    }

    #[test]
    fn round_trip() {
        let file = sample();
        let mut r = Reader::open(&file, "1.2.3").unwrap();
        assert_eq!(r.u32().unwrap(), 7);
        assert_eq!(r.str().unwrap(), "lamp");
        assert_eq!(r.f32s().unwrap(), [1.0, 2.5]);
        assert_eq!(r.u64s().unwrap(), [u64::MAX]);
        assert!(r.bool().unwrap());
        r.end().unwrap();
    }

    #[test]
    fn the_checksum_catches_any_flipped_bit_and_a_trailing_zero() {
        // Known answer: the empty payload is one step with its length, 0.
        assert_eq!(
            checksum(&[]),
            0xcbf2_9ce4_8422_2325u64.wrapping_mul(0x0100_0000_01b3)
        );
        let payload: Vec<u8> = (0..37u32).map(|i| (i * 29 % 251) as u8).collect();
        let sum = checksum(&payload);
        for i in 0..payload.len() {
            for bit in 0..8 {
                let mut damaged = payload.clone();
                damaged[i] ^= 1 << bit;
                assert_ne!(checksum(&damaged), sum, "byte {i} bit {bit}");
            }
        }
        // Zeros the padding of the last word would hide are told apart by the length.
        let mut longer = payload.clone();
        longer.push(0);
        assert_ne!(checksum(&longer), sum);
    }

    #[test]
    fn damaged_truncated_foreign_and_other_versions_are_refused() {
        let file = sample();
        assert!(
            Reader::open(&file, "1.2.4")
                .unwrap_err()
                .contains("written by lightbake 1.2.3")
        );
        for cut in [0, 5, 12, file.len() - 1] {
            assert!(Reader::open(&file[..cut], "1.2.3").is_err(), "cut at {cut}");
        }
        let mut flipped = file.clone();
        *flipped.last_mut().unwrap() ^= 1;
        assert!(
            Reader::open(&flipped, "1.2.3")
                .unwrap_err()
                .contains("checksum")
        );
        assert!(
            Reader::open(b"GIF89a..........", "1.2.3")
                .unwrap_err()
                .contains("not a lightbake cache")
        );
        // A length far beyond the payload is refused before anything is allocated.
        let mut w = Writer::default();
        w.u64(u64::MAX / 2);
        let file = w.finish("v");
        let mut r = Reader::open(&file, "v").unwrap();
        assert!(r.f32s().unwrap_err().contains("elements"));
    }
}
