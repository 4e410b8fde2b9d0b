//! Point-cloud file formats (being written).
