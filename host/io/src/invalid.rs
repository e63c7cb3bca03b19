//! Refusing input that cannot be used, in one way for every crate: each crate's error
//! type says how it holds such a refusal ([`Invalid`]), and [`invalid!`](crate::invalid)
//! and [`require!`](crate::require) return one from the function they are in.

/// An error that can say "this input cannot be used, because …".
pub trait Invalid {
    /// The error for input refused with `message` (which names the input and the field).
    fn invalid(message: String) -> Self;
}

/// Returns, from the function it is in, its error type's [`Invalid::invalid`] with a
/// formatted message.
#[macro_export]
macro_rules! invalid {
    ($($message:tt)*) => {
        return Err($crate::invalid::Invalid::invalid(format!($($message)*)))
    };
}

/// [`invalid!`](crate::invalid) unless `$condition` holds.
#[macro_export]
macro_rules! require {
    ($condition:expr, $($message:tt)*) => {
        // Bound first, so a comparison with NaN fails the requirement.
        let holds: bool = $condition;
        if !holds {
            $crate::invalid!($($message)*);
        }
    };
}

#[cfg(test)]
mod tests {
    use super::Invalid;

    #[derive(Debug, PartialEq)]
    struct Refused(String);

    impl Invalid for Refused {
        fn invalid(message: String) -> Self {
            Refused(message)
        }
    }

    fn positive(v: f64) -> Result<f64, Refused> {
        crate::require!(v > 0.0, "v must be positive, got {v}");
        Ok(v)
    }

    #[test]
    fn a_requirement_refuses_what_fails_it_nan_included() {
        assert_eq!(positive(2.0), Ok(2.0));
        assert_eq!(
            positive(-1.0),
            Err(Refused("v must be positive, got -1".into()))
        );
        assert!(positive(f64::NAN).is_err());
    }
}
