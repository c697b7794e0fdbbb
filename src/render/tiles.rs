//! render: tiles
