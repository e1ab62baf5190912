//! An adaptive binary range coder (the LZMA scheme: 11-bit probabilities that move 1/32 of
//! the way toward each coded bit, carries propagated through a cached byte; version 4's
//! probabilities move faster while they have seen few bits). `.czs` versions 3 and 4 code
//! their curves with it: turns, side angles and contrasts repeat along a curve, so a
//! probability per context takes a primitive from 18 bits to a third of that. Integer-only,
//! so the bytes are the same on every machine. Sequential by nature: CPU.

const TOP: u32 = 1 << 24;
const PROB_BITS: u32 = 11;
const ONE: u16 = 1 << PROB_BITS;
const MOVE: u32 = 5;
/// Widest range [`Encoder::uniform`] codes in one step (wider ones take two).
const UNIFORM_MAX: u32 = 1 << 16;

/// A probability of a 0 bit, in units of 2⁻¹¹, and how many bits it has seen (up to 255).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Prob {
    p: u16,
    seen: u8,
}
pub const HALF: Prob = Prob {
    p: ONE / 2,
    seen: 0,
};

impl Prob {
    /// Moves toward the coded bit: by 1/32 always (`warm` false, version 3), or (`warm`) by
    /// 1/2, 1/4, 1/4, 1/8 … for the first bits a probability sees, about the running mean,
    /// so a context that is seen a few times only pays little to learn (version 4).
    fn update(&mut self, bit: bool, warm: bool) {
        let shift = if warm {
            (1 + (self.seen as u32 + 1).ilog2()).min(MOVE)
        } else {
            MOVE
        };
        self.seen = self.seen.saturating_add(1);
        if bit {
            self.p -= self.p >> shift;
        } else {
            self.p += (ONE - self.p) >> shift;
        }
    }
}

pub struct Encoder {
    low: u64,
    range: u32,
    cache: u8,
    pending: u64,
    out: Vec<u8>,
    first: bool,
    warm: bool,
    /// When measuring: the information each coded bit carried (−log2 of its probability),
    /// summed per tag ([`Encoder::tag`]), so that a file's bits can be split by what they
    /// code. None when just encoding.
    ledger: Option<Vec<f64>>,
    tag: usize,
}

impl Default for Encoder {
    fn default() -> Self {
        Encoder {
            low: 0,
            range: u32::MAX,
            cache: 0,
            pending: 1,
            out: Vec::new(),
            first: true,
            warm: false,
            ledger: None,
            tag: 0,
        }
    }
}

impl Encoder {
    /// `warm`: probabilities learn fast at first (see [`Prob`]), as version 4 codes;
    /// otherwise as version 3.
    pub fn new(warm: bool) -> Self {
        Encoder {
            warm,
            ..Default::default()
        }
    }

    /// An encoder that also keeps a ledger of `tags` entries (see [`Encoder::ledger`]).
    pub fn measuring(warm: bool, tags: usize) -> Self {
        Encoder {
            warm,
            ledger: Some(vec![0.0; tags]),
            ..Default::default()
        }
    }

    /// What the next symbols are charged to in the ledger (when there is one).
    pub fn tag(&mut self, t: usize) {
        self.tag = t;
    }

    /// Bits of information charged to each tag so far; None unless [`Encoder::measuring`].
    /// Their sum is the coded length less the coder's own overhead (under 4 bytes a stream).
    pub fn ledger(&self) -> Option<&[f64]> {
        self.ledger.as_deref()
    }

    fn charge(&mut self, bits: f64) {
        if let Some(l) = &mut self.ledger {
            l[self.tag] += bits;
        }
    }

    fn shift_low(&mut self) {
        if (self.low as u32) < 0xFF00_0000 || (self.low >> 32) != 0 {
            let carry = (self.low >> 32) as u8;
            let mut byte = self.cache;
            loop {
                // The scheme's first byte is always 0: left out, and put back by the decoder.
                if !std::mem::take(&mut self.first) {
                    self.out.push(byte.wrapping_add(carry));
                }
                byte = 0xFF;
                self.pending -= 1;
                if self.pending == 0 {
                    break;
                }
            }
            self.cache = (self.low >> 24) as u8;
        }
        self.pending += 1;
        self.low = (self.low & 0x00FF_FFFF) << 8;
    }

    pub fn bit(&mut self, p: &mut Prob, bit: bool) {
        if self.ledger.is_some() {
            let zero = p.p as f64 / ONE as f64;
            self.charge(-(if bit { 1.0 - zero } else { zero }).log2());
        }
        let bound = (self.range >> PROB_BITS) * p.p as u32;
        if bit {
            self.low += bound as u64;
            self.range -= bound;
        } else {
            self.range = bound;
        }
        p.update(bit, self.warm);
        while self.range < TOP {
            self.range <<= 8;
            self.shift_low();
        }
    }

    /// The low `n` bits of `v`, most significant first, through a binary tree of
    /// probabilities (`probs` has 2ⁿ entries; entry 0 unused).
    pub fn tree(&mut self, probs: &mut [Prob], n: u32, v: u32) {
        let mut m = 1usize;
        for i in (0..n).rev() {
            let b = (v >> i) & 1 == 1;
            self.bit(&mut probs[m], b);
            m = (m << 1) | b as usize;
        }
    }

    /// `v` in 0..n, every value equally likely: log2 n bits, no probability to learn.
    pub fn uniform(&mut self, v: u32, n: u32) {
        debug_assert!(v < n);
        if n > UNIFORM_MAX {
            // Wide ranges in two parts, so that range / n keeps enough precision.
            self.uniform(v % UNIFORM_MAX, UNIFORM_MAX);
            return self.uniform(v / UNIFORM_MAX, (n - 1) / UNIFORM_MAX + 1);
        }
        self.charge((n as f64).log2());
        let r = self.range / n;
        self.low += v as u64 * r as u64;
        self.range = r;
        while self.range < TOP {
            self.range <<= 8;
            self.shift_low();
        }
    }

    pub fn finish(mut self) -> Vec<u8> {
        for _ in 0..5 {
            self.shift_low();
        }
        // Trailing zero bytes carry nothing: the decoder reads zeros past the end.
        while self.out.last() == Some(&0) {
            self.out.pop();
        }
        self.out
    }
}

pub struct Decoder<'a> {
    data: &'a [u8],
    pos: usize,
    range: u32,
    code: u32,
    warm: bool,
}

impl<'a> Decoder<'a> {
    /// `warm`: as the encoder was made (see [`Encoder::new`]).
    pub fn new(data: &'a [u8], warm: bool) -> Self {
        let mut d = Decoder {
            data,
            pos: 0,
            range: u32::MAX,
            code: 0,
            warm,
        };
        // The encoder's leading 0 byte is implied; four more fill the code.
        for _ in 0..4 {
            d.code = (d.code << 8) | d.next() as u32;
        }
        d
    }

    fn next(&mut self) -> u8 {
        let b = self.data.get(self.pos).copied().unwrap_or(0);
        self.pos += 1;
        b
    }

    /// Bytes read past the end of the data (zeros stand in for those the encoder trimmed).
    pub fn overrun(&self) -> usize {
        self.pos.saturating_sub(self.data.len())
    }

    pub fn bit(&mut self, p: &mut Prob) -> bool {
        let bound = (self.range >> PROB_BITS) * p.p as u32;
        let bit = if self.code < bound {
            self.range = bound;
            false
        } else {
            self.code -= bound;
            self.range -= bound;
            true
        };
        p.update(bit, self.warm);
        while self.range < TOP {
            self.range <<= 8;
            self.code = (self.code << 8) | self.next() as u32;
        }
        bit
    }

    /// [`Encoder::uniform`] read back; a damaged stream may give any value in 0..n.
    pub fn uniform(&mut self, n: u32) -> u32 {
        if n > UNIFORM_MAX {
            let lo = self.uniform(UNIFORM_MAX);
            return lo + UNIFORM_MAX * self.uniform((n - 1) / UNIFORM_MAX + 1);
        }
        let r = self.range / n;
        let v = (self.code / r).min(n - 1);
        self.code -= v * r;
        self.range = r;
        while self.range < TOP {
            self.range <<= 8;
            self.code = (self.code << 8) | self.next() as u32;
        }
        v
    }

    pub fn tree(&mut self, probs: &mut [Prob], n: u32) -> u32 {
        let mut m = 1usize;
        for _ in 0..n {
            m = (m << 1) | self.bit(&mut probs[m]) as usize;
        }
        (m - (1 << n)) as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bits_round_trip_and_skewed_bits_cost_little() {
        // A skewed source (1 in 16 ones), a uniform one, and runs of each.
        let mut state = 12345u64;
        let mut rnd = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as u32
        };
        let bits: Vec<bool> = (0..40_000)
            .map(|k| match k / 10_000 {
                0 => rnd() % 16 == 0,
                1 => rnd() % 2 == 0,
                2 => true,
                _ => false,
            })
            .collect();
        for warm in [false, true] {
            let mut e = Encoder::new(warm);
            let mut p = [HALF; 4];
            for (k, &b) in bits.iter().enumerate() {
                e.bit(&mut p[k / 10_000], b);
            }
            let out = e.finish();
            let mut d = Decoder::new(&out, warm);
            let mut q = [HALF; 4];
            for (k, &b) in bits.iter().enumerate() {
                assert_eq!(d.bit(&mut q[k / 10_000]), b, "bit {k}");
            }
            // Entropy: 10k·0.337 + 10k·1 bits ≈ 1,670 B, plus the runs' few bytes.
            assert!(out.len() < 1_800, "{} bytes", out.len());
            assert!(out.len() > 1_600, "{} bytes", out.len());
        }
    }

    /// A probability that sees few bits learns them faster when warm: 12 contexts of 8
    /// skewed bits each cost less, and a decoder made the other way reads them wrong.
    #[test]
    fn warm_probabilities_learn_short_contexts_cheaply() {
        let bits: Vec<bool> = (0..96).map(|k| k % 8 == 7).collect();
        let code = |warm: bool| {
            let mut e = Encoder::new(warm);
            let mut p = [HALF; 12];
            for (k, &b) in bits.iter().enumerate() {
                e.bit(&mut p[k / 8], b);
            }
            e.finish()
        };
        let (cold, warm) = (code(false), code(true));
        assert!(warm.len() < cold.len(), "{} vs {}", warm.len(), cold.len());
        let read = |data: &[u8], warm: bool| {
            let mut d = Decoder::new(data, warm);
            let mut q = [HALF; 12];
            (0..96).map(|k| d.bit(&mut q[k / 8])).collect::<Vec<_>>()
        };
        assert_eq!(read(&warm, true), bits);
        assert_ne!(read(&warm, false), bits);
    }

    /// Uniform values of every width round trip between adaptive bits, and cost their
    /// log2 n bits.
    #[test]
    fn uniform_values_round_trip_and_cost_log2_n() {
        let ns = [1u32, 2, 3, 7, 513, 65_536, 65_537, 1 << 20, u32::MAX];
        let vals: Vec<(u32, u32)> = (0..600u32)
            .map(|k| {
                let n = ns[k as usize % ns.len()];
                (k.wrapping_mul(2_654_435_761) % n, n)
            })
            .collect();
        let mut e = Encoder::new(true);
        let mut p = HALF;
        for (k, &(v, n)) in vals.iter().enumerate() {
            e.uniform(v, n);
            e.bit(&mut p, k % 5 == 0);
        }
        let out = e.finish();
        let mut d = Decoder::new(&out, true);
        let mut q = HALF;
        for (k, &(v, n)) in vals.iter().enumerate() {
            assert_eq!(d.uniform(n), v, "value {k}");
            assert_eq!(d.bit(&mut q), k % 5 == 0, "bit {k}");
        }
        let bits: f64 = vals.iter().map(|&(_, n)| (n as f64).log2()).sum();
        let skewed = 600.0 * 0.722; // the bits' entropy, 1 in 5
        let got = out.len() as f64 * 8.0;
        assert!(
            got < bits + skewed + 100.0,
            "{got} bits for {bits} + {skewed}"
        );
        assert!(got > bits, "{got} bits for {bits}");
    }

    #[test]
    fn trees_round_trip_every_value() {
        let mut e = Encoder::default();
        let mut p = vec![HALF; 16];
        for v in (0..16).chain((0..16).rev()) {
            e.tree(&mut p, 4, v);
        }
        let out = e.finish();
        let mut d = Decoder::new(&out, false);
        let mut q = vec![HALF; 16];
        for v in (0..16).chain((0..16).rev()) {
            assert_eq!(d.tree(&mut q, 4), v);
        }
        // Nothing coded: nothing written.
        assert!(Encoder::default().finish().is_empty());
    }
}
