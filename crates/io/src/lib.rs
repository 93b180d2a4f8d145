//! slamkit-io: readers and writers for datasets, trajectories and maps.
//!
//! Every reader returns a typed error naming the file and line or frame on bad input; none
//! panics.
