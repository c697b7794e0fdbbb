//! render: sample
