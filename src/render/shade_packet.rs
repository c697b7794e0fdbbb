//! render: shade_packet
