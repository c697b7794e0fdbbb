//! render: shade
