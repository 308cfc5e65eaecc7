//! FFT lengths that rustfft handles fastest (products of 2, 3 and 5).

fn is_fast(mut n: usize) -> bool {
    if n == 0 {
        return false;
    }
    for p in [2, 3, 5] {
        while n % p == 0 {
            n /= p;
        }
    }
    n == 1
}

/// Smallest even 2^a 3^b 5^c that is >= n.
pub fn fast_len_at_least(n: usize) -> usize {
    let mut m = n.max(2);
    m += m % 2;
    while !is_fast(m) {
        m += 2;
    }
    m
}

/// Largest even 2^a 3^b 5^c that is <= n (n >= 2).
pub fn fast_len_at_most(n: usize) -> usize {
    let mut m = n - n % 2;
    while m > 2 && !is_fast(m) {
        m -= 2;
    }
    m.max(2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lengths() {
        assert_eq!(fast_len_at_least(4681), 4800);
        assert_eq!(fast_len_at_least(10_000), 10_000);
        assert_eq!(fast_len_at_most(122_571), 121_500);
        assert_eq!(fast_len_at_most(243_938), 243_000);
    }
}
