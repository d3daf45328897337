//! AIM frame format (work in progress).
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![warn(missing_docs)]
