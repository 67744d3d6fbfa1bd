// The SVA's matching-cost stage, as the chip plan describes it (sva/hamming/timing.py:
// hamming_stage; the cost is sva/hamming/cost.py's definition, the hybrid's weighted two parts included).
//
// Structure (never delay registers added to meet a number: the cycles come from it):
// - an input register takes a pixel (its left descriptor, the D right descriptors of its
//   window, which of them lie outside the right image, and the weight registers) in the cycle
//   in_valid is high, if the stage is free;
// - G = ceil(D / LANES) lane groups: in the G cycles after, LANES disparities a cycle each go
//   through an XOR and the popcount tree of each descriptor part -- lg(B) levels of two-input
//   adders --, then (two parts) a level that weights each distance (w in 0..3: the distance,
//   itself shifted left by one, or their sum) and a level that adds the two;
// - the tree settles V adder levels a cycle: a pipeline register after every V levels, the
//   output register after the last, so a lane group takes T = ceil(levels / V) cycles;
// - the last lane group's costs are written with the others' into the output register:
//   out_valid is high in cycle t0 + G + T for a pixel taken in cycle t0.
// Cycles are the lock-step pipeline's ticks: with en low every register holds (the model's
// stall; the SVA top, sva_top.sv, drives it), with en high the stage advances.
// So the stage takes a pixel every G cycles (II = G) and its latency is G + T -- the plan's rule
// "G + tree(lg(bits))" (one part), "G + tree(lg(max b_k) + 2)" (the hybrid).
module sva_hamming #(
    parameter int D = 16,       // disparities
    parameter int LANES = 16,   // disparities a cycle
    parameter int V = 8,        // adder levels that settle in one cycle
    parameter int B0 = 32,      // bits of the first part (the CNN's, or the only part)
    parameter int B1 = 0,       // bits of the second part (the hybrid's census; 0: none)
    parameter int COST_W = 8    // bits of a cost (the largest: w0 B0 + w1 B1)
) (
    input  logic                      clk,
    input  logic                      rst,
    input  logic                      en,        // the pipeline advances (0: every register holds)
    input  logic                      in_valid,
    output logic                      in_ready,
    input  logic [B0+B1-1:0]          dl,
    input  logic [D*(B0+B1)-1:0]      dr,        // dr[d]: the right descriptor at x - d
    input  logic [D-1:0]              outside,   // x - d < 0: the largest cost
    input  logic [1:0]                w0,
    input  logic [1:0]                w1,
    output logic                      out_valid,
    output logic [D*COST_W-1:0]       cost
);
  localparam int W = B0 + B1;
  localparam int G = (D + LANES - 1) / LANES;
  localparam int BMAX = (B0 > B1) ? B0 : B1;
  localparam int LG = $clog2(BMAX);                 // popcount levels
  localparam int LEVELS = LG + ((B1 > 0) ? 2 : 0);  // + weight, + sum
  localparam int T = (LEVELS + V - 1) / V;          // cycles through the tree
  localparam int N = 1 << LG;                       // leaves, padded to a power of two
  localparam int GW = (G > 1) ? $clog2(G) : 1;

  // ---- the input register and the lane-group counter -----------------------------------
  logic [W-1:0]     dl_q;
  logic [D*W-1:0]   dr_q;
  logic [D-1:0]     out_q;
  logic [1:0]       w0_q, w1_q;
  logic [GW-1:0]    group;     // the lane group going into the tree
  logic             busy;      // lane groups of the taken pixel still to go
  assign in_ready = !busy || (group == GW'(G - 1));
  always_ff @(posedge clk) if (en || rst) begin
    if (rst) begin
      busy <= 1'b0;
      group <= '0;
    end else begin
      if (busy) group <= (group == GW'(G - 1)) ? '0 : group + 1'b1;
      if (in_valid && in_ready) begin
        dl_q <= dl; dr_q <= dr; out_q <= outside; w0_q <= w0; w1_q <= w1;
        busy <= 1'b1;
      end else if (busy && group == GW'(G - 1)) begin
        busy <= 1'b0;
      end
    end
  end

  // ---- per lane: XOR, the parts' popcount trees, weighting, sum; a register every V levels --
  // lvl[l].v[lane][k]: node k of level l (level 0: the bits); a part's tree has N leaves
  logic [COST_W-1:0] lane_cost [LANES];
  logic [GW-1:0]     lane_group_at_end;
  logic              valid_at_end;

  genvar ln, l, k;
  generate
    for (ln = 0; ln < LANES; ln++) begin : lane
      localparam int DI_MAX = D;  // a lane of the last group may have no disparity
      logic [W-1:0] x;
      logic         oob;
      always_comb begin
        int di;
        di = int'(group) * LANES + ln;
        x = '0;
        oob = 1'b1;
        if (di < DI_MAX) begin
          x = dl_q ^ dr_q[di*W +: W];
          oob = out_q[di];
        end
      end
      // two parts' trees side by side (part 1 empty when B1 = 0)
      for (l = 0; l <= LEVELS; l++) begin : lvl
        // a register after every V levels; the output register ends the last V
        localparam bit REG = (l > 0) && (l < LEVELS) && (l % V == 0);
        logic [COST_W-1:0] p0 [N];    // part 0's nodes at this level (N >> l used)
        /* verilator lint_off UNUSEDSIGNAL */
        logic [COST_W-1:0] p1 [N];  // (the sum level leaves part 1's last nodes unread)
        /* verilator lint_on UNUSEDSIGNAL */
        logic              o;         // outside, carried along
        logic [1:0]        a0, a1;    // the weights, carried along
        logic [COST_W-1:0] c0 [N];
        logic [COST_W-1:0] c1 [N];
        logic              co;
        logic [1:0]        ca0, ca1;
        if (l == 0) begin : leaves
          for (k = 0; k < N; k++) begin : leaf
            assign c0[k] = (k < B0) ? COST_W'(x[k]) : '0;
            assign c1[k] = (k < B1) ? COST_W'(x[B0 + k]) : '0;
          end
          assign co = oob; assign ca0 = w0_q; assign ca1 = w1_q;
        end else begin : node
          for (k = 0; k < N; k++) begin : add
            if (l <= LG) begin : popcount
              if (k < (N >> l)) begin : live
                assign c0[k] = lvl[l-1].p0[2*k] + lvl[l-1].p0[2*k+1];
                assign c1[k] = lvl[l-1].p1[2*k] + lvl[l-1].p1[2*k+1];
              end else begin : idle
                assign c0[k] = '0; assign c1[k] = '0;
              end
            end else if (l == LG + 1) begin : weigh  // w h = (w[0] ? h : 0) + (w[1] ? 2h : 0)
              if (k == 0) begin : live
                assign c0[k] = (lvl[l-1].a0[0] ? lvl[l-1].p0[0] : '0)
                             + (lvl[l-1].a0[1] ? (lvl[l-1].p0[0] << 1) : '0);
                assign c1[k] = (lvl[l-1].a1[0] ? lvl[l-1].p1[0] : '0)
                             + (lvl[l-1].a1[1] ? (lvl[l-1].p1[0] << 1) : '0);
              end else begin : idle
                assign c0[k] = '0; assign c1[k] = '0;
              end
            end else begin : sum
              if (k == 0) begin : live
                assign c0[k] = lvl[l-1].p0[0] + lvl[l-1].p1[0];
                assign c1[k] = '0;
              end else begin : idle
                assign c0[k] = '0; assign c1[k] = '0;
              end
            end
          end
          assign co = lvl[l-1].o; assign ca0 = lvl[l-1].a0; assign ca1 = lvl[l-1].a1;
        end
        if (REG) begin : pipe
          always_ff @(posedge clk) if (en || rst) begin
            p0 <= c0; p1 <= c1; o <= co; a0 <= ca0; a1 <= ca1;
          end
        end else begin : wire_
          assign p0 = c0; assign p1 = c1; assign o = co; assign a0 = ca0; assign a1 = ca1;
        end
      end
      // the largest cost where x - d < 0
      assign lane_cost[ln] = lvl[LEVELS].o
          ? COST_W'(((B1 > 0) ? int'(lvl[LEVELS].a0) : 1) * B0 + int'(lvl[LEVELS].a1) * B1)
          : lvl[LEVELS].p0[0];
    end
  endgenerate

  // which lane group leaves the tree now: the group counter and 'busy' delayed by the T - 1
  // registers inside the tree
  logic [GW-1:0] grp_d [T];
  logic          vld_d [T];
  assign grp_d[0] = group;
  assign vld_d[0] = busy;
  genvar t;
  generate
    for (t = 1; t < T; t++) begin : delay
      always_ff @(posedge clk) if (en || rst) begin
        if (rst) vld_d[t] <= 1'b0; else vld_d[t] <= vld_d[t-1];
        grp_d[t] <= grp_d[t-1];
      end
    end
  endgenerate
  assign lane_group_at_end = grp_d[T-1];
  assign valid_at_end = vld_d[T-1];

  // ---- the output register: each lane group's costs in their place -----------------------
  always_ff @(posedge clk) if (en || rst) begin
    if (rst) begin
      out_valid <= 1'b0;
    end else begin
      out_valid <= valid_at_end && (lane_group_at_end == GW'(G - 1));
      if (valid_at_end) begin
        for (int i = 0; i < LANES; i++) begin
          if (int'(lane_group_at_end) * LANES + i < D)
            cost[(int'(lane_group_at_end) * LANES + i) * COST_W +: COST_W] <= lane_cost[i];
        end
      end
    end
  end
endmodule
