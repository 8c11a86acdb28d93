//! Image quality metrics (the Dr.Bokeh paper's Table 1).
