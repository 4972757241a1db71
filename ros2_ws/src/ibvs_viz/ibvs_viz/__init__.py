"""ibvs_viz: what RViz and Foxglove show of the cell (see viz_node)."""
