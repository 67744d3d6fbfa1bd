// The SVA's SGM path units and path sum, as the chip plan describes them (sva/sgm/timing.py:
// sgm_stage, "sgm": II = max(the left path's recurrence G - 1 + tree(5) + tree(lg(L) + [G > 1]),
// the previous row's ports), latency G + tree(5); "path_sum": II = G, latency tree(lg(paths) +
// 1); left_path_ii -- the plan's rules since this twin showed its earlier G + tree(lg(L) + [G >
// 1]) and tree(lg(paths)) short for V < 5). The arithmetic is sva/sgm/sgm.py's (sgm_ref): per path r
//   L_r(p, d) = min(A(p, d) + min(L'(d), L'(d - 1) + P1, L'(d + 1) + P1, m' + P2) - m', cap)
// with L' = L_r(p - r, .), m' its minimum over d, the absent d - 1 < 0 and d + 1 >= D left out,
// L_r(p, .) = min(A, cap) where p - r lies outside the image, cap = 2^PATH_W - 1, the adaptive
// P2 = max(P1, P2 - ((slope |I(p) - I(p - r)|) >> 4)), and S = min(sum of the enabled paths,
// 2^SUM_W - 1). Paths, in the model's order: 0 left-to-right (predecessor x - 1), 1 top (x,
// y - 1), 2 top-left (x - 1, y - 1), 3 top-right (x + 1, y - 1); `paths` = n enables the first n.
//
// Interface (a stage of a lock-step pipeline): en (0: every register and memory port holds);
// a pixel is taken in a cycle with en, in_valid and in_ready, in raster order: its D costs a
// (A, clamped or not: the cap is applied here), its grey level and the grey levels of x - 1, x
// and x + 1 in row y - 1 (grey_up: the top rides them with the descriptor rows), and x_first,
// x_last, y_first. Run-time registers: ngroups = G, dn = D, width = W, p1, p2, adaptive, slope,
// paths. lc_valid: for one advancing cycle, lc holds the pixel's path costs (path k's D costs
// at k D_MAX); s_valid: s holds its D sums S.
//
// Structure (the cycles come from it):
// - a pixel taken in cycle t: its input register (with the four P2s: the adaptive P2's
//   multiply-shift-max is computed from the grey levels in the taking cycle, outside the
//   counted levels), and the reads of the top paths' previous-row memories: lane group g's word
//   in cycle t + g, the predecessor's minimum in cycle t;
// - lane group g in cycle t + 1 + g: per lane and path, five levels -- Lp(d) - m' and
//   min(Lp(d - 1), Lp(d + 1)); + (P1 - m') and min(., P2'); min; + A; min(., cap) -- tree(5)
//   cycles, into the path-cost register (the left path's predecessor for the next pixel);
// - the minimum over the group's lanes, lg(L) levels, then (G_MAX > 1) one level folding it
//   into the running minimum: tree(lg(L) + [G_MAX > 1]) cycles, then the pixel's minimum m;
// - the top paths' memories (W_MAX + 2 slots of G_MAX words, one read and one write port): a
//   ring per path, written at slot s and read at slot s + 1 (top: W + 1 slots, top-left W + 2,
//   top-right W), so pixel (x, y) reads what (x, y - 1), (x - 1, y - 1) or (x + 1, y - 1)
//   wrote. A word holds a group's L lanes and the next group's first cost (the d + 1 of its
//   last lane: L + 1 entries), written once that group is computed; a side ring holds each
//   pixel's minimum;
// - ONE_PORT = 1 (sva.sram_ports = "1rw"): each of those memories has one port, one access a
//   cycle (one address, one write enable, the read register). Reads keep their cycles (the
//   latency does not change); a write that meets a read waits in a queue of pending writes
//   and is written in the first cycle without a read. With the top paths on (paths > 1) a
//   pixel is taken when the row words waiting (queued or arriving) fit in the cycles between
//   its own reads (t .. t + G - 1) and its own first write (t + tree(5) + 1): tree(5) + 1 - G
//   of them, none when G > tree(5). A word is read again W - 1 pixels or more after it is
//   written (top-right), its queue long empty for W >= 3. The minima's ring is read at a
//   take and written once a pixel, at least two cycles apart: its write waits a cycle at most;
// - the path sum: per lane the enabled paths' costs added (lg(4) levels) and saturated (one
//   level): tree(3) cycles after the path costs.
// So the next pixel's group 0 may start once m is registered: II = G + tree(5) - 1 + tree(lg(L)
// + [G_MAX > 1]) (the plan's, with G_MAX the build's), with one port and paths > 1 at least
// 2 G (G reads and G writes a pixel); the path costs leave G + tree(5) cycles after the pixel
// is taken; the sums tree(3) after them (the plan's tree(lg(paths) + 1) for four paths, or
// where V >= 3).
module sva_sgm #(
    parameter int D_MAX = 32,
    parameter int LANES = 16,
    parameter int V = 8,
    parameter int W_MAX = 24,
    parameter int A_W = 8,       // bits of an aggregated cost (sva.cost_bits)
    parameter int PATH_W = 9,    // sva.path_bits
    parameter int SUM_W = 10,    // sva.sum_bits
    parameter bit ONE_PORT = 0   // the previous rows' memories: 0 a read and a write port, 1 one
) (
    input  logic                      clk,
    input  logic                      rst,
    input  logic                      en,
    input  logic [7:0]                ngroups,
    input  logic [8:0]                dn,
    input  logic [7:0]                width,
    input  logic [14:0]               p1,
    input  logic [14:0]               p2,
    input  logic                      adaptive,
    input  logic [14:0]               slope,
    input  logic [2:0]                paths,
    input  logic                      in_valid,
    output logic                      in_ready,
    input  logic [D_MAX*A_W-1:0]      a,
    input  logic [7:0]                grey,
    input  logic [23:0]               grey_up,   // row y - 1 at x - 1, x, x + 1
    input  logic                      x_first,
    input  logic                      x_last,
    input  logic                      y_first,
    output logic                      lc_valid,
    output logic [4*D_MAX*PATH_W-1:0] lc,
    output logic                      s_valid,
    output logic [D_MAX*SUM_W-1:0]    s
);
  localparam int G_MAX = (D_MAX + LANES - 1) / LANES;
  localparam int GW = (G_MAX > 1) ? $clog2(G_MAX) : 1;
  localparam int SLOTS = W_MAX + 2;
  localparam int IW = 18;                        // signed arithmetic: A + P2 < 2^17
  localparam int TA = (5 + V - 1) / V;           // the recurrence's arithmetic: tree(5)
  localparam int LGL = $clog2(LANES);
  localparam int ML = LGL + ((G_MAX > 1) ? 1 : 0);   // the minimum's levels, with the fold
  localparam int TT = (ML + V - 1) / V;          // tree(lg(L) + [G_MAX > 1])
  localparam int TP = (3 + V - 1) / V;           // the path sum: tree(lg(4) + 1)
  localparam int LN = 1 << LGL;
  localparam logic [PATH_W-1:0] BIG = '1;        // an absent neighbour: never below a cost
  localparam int WORD = (LANES + 1) * PATH_W;

  // ---- taking a pixel: the input register, the P2s, the rings' slots ------------------------
  logic [GW-1:0]      group;
  logic               busy;
  logic               take;
  wire  [GW-1:0]      last_g = GW'(int'(ngroups) - 1);
  logic [D_MAX*A_W-1:0] a_q;
  logic [15:0]        pen_q [4];    // each path's P2 for this pixel
  logic [3:0]         start_q;      // the predecessor lies outside the image
  logic [7:0]         grey_left;    // the previous pixel's grey level
  logic [7:0]         wslot [4], rslot [4], wslot_q [4];

  // the P2 of a step from a pixel of grey i_q to one of grey i_p (sva/sgm/sgm.py effective_p2)
  function automatic logic [15:0] pen(input logic [7:0] i_p, input logic [7:0] i_q);
    logic [7:0]         diff;
    logic [31:0]        lower;
    logic signed [24:0] lowered;
    diff = (i_p > i_q) ? i_p - i_q : i_q - i_p;
    lower = (32'(slope) * 32'(diff)) >> 4;
    lowered = $signed({10'd0, p2}) - $signed({1'b0, lower[23:0]});
    if (!adaptive) pen = {1'b0, p2};
    else if (lowered < $signed({10'd0, p1})) pen = {1'b0, p1};
    else pen = lowered[15:0];
  endfunction

  // ring slots: the pixel writes slot w and reads w + 1 (mod the ring's size); path 0: none
  logic [7:0] ptr [4];
  always_comb begin
    for (int k = 0; k < 4; k++) begin
      int n;
      n = (k == 1) ? int'(width) + 1 : (k == 2) ? int'(width) + 2 : int'(width);
      wslot[k] = (x_first && y_first) ? 8'd0 : ptr[k];
      rslot[k] = (int'(wslot[k]) + 1 >= n) ? 8'd0 : wslot[k] + 8'd1;
    end
  end

  always_ff @(posedge clk) begin
    if (rst) begin
      busy <= 1'b0;
      group <= '0;
      for (int k = 0; k < 4; k++) ptr[k] <= '0;
    end else if (en) begin
      if (take) begin
        a_q <= a;
        pen_q[0] <= pen(grey, grey_left);
        pen_q[1] <= pen(grey, grey_up[15:8]);
        pen_q[2] <= pen(grey, grey_up[7:0]);
        pen_q[3] <= pen(grey, grey_up[23:16]);
        start_q <= {y_first || x_last, y_first || x_first, y_first, x_first};
        grey_left <= grey;
        for (int k = 0; k < 4; k++) begin
          wslot_q[k] <= wslot[k];
          ptr[k] <= rslot[k];
        end
      end
      if (take) begin
        busy <= 1'b1;
        group <= '0;
      end else if (busy && group == last_g) begin
        busy <= 1'b0;
      end else if (busy) begin
        group <= group + 1'b1;
      end
    end
  end

  // ---- the top paths' previous-row memories (word g of a slot) and minima -------------------
  logic [WORD-1:0]   row_mem [4][SLOTS * G_MAX];
  logic [PATH_W-1:0] min_mem [4][SLOTS];
  logic [WORD-1:0]   row_rd [4];
  logic [PATH_W-1:0] min_rd [4];
  wire               rd_v = take || (busy && group != last_g);   // word g + 1 for group g + 1
  wire  [GW-1:0]     rd_g = take ? '0 : group + 1'b1;
  logic              row_we;
  logic [GW-1:0]     row_wg;
  logic [WORD-1:0]   row_wd [4];
  logic              min_we;
  logic [PATH_W-1:0] min_wd [4];
  logic       port_ok;     // the memories' ports can take a pixel
  logic [7:0] rslot_q [4];
  always_ff @(posedge clk) if (en && take) rslot_q <= rslot;
  // ONE_PORT = 1: each memory's one access this cycle (one_port below picks it)
  localparam int RAW = $clog2(SLOTS * G_MAX);
  logic              op_rd, op_we, om_rd, om_we;
  logic [RAW-1:0]    op_addr [4];
  logic [WORD-1:0]   op_wd [4];
  logic [7:0]        om_addr [4];
  logic [PATH_W-1:0] om_wd [4];
  always_ff @(posedge clk) begin
    if (en) begin
      if (!ONE_PORT) begin   // a read and a write port each
        for (int k = 1; k < 4; k++) begin
          if (rd_v)
            row_rd[k] <= row_mem[k][int'(take ? rslot[k] : rslot_q[k]) * G_MAX + int'(rd_g)];
          if (take) min_rd[k] <= min_mem[k][rslot[k]];
          if (row_we) row_mem[k][int'(wslot_q[k]) * G_MAX + int'(row_wg)] <= row_wd[k];
          if (min_we) min_mem[k][wslot_q[k]] <= min_wd[k];
        end
      end else begin         // one port each: one address, one write enable
        for (int k = 1; k < 4; k++) begin
          if (op_we) row_mem[k][op_addr[k]] <= op_wd[k];
          else if (op_rd) row_rd[k] <= row_mem[k][op_addr[k]];
          if (om_we) min_mem[k][om_addr[k]] <= om_wd[k];
          else if (om_rd) min_rd[k] <= min_mem[k][om_addr[k]];
        end
      end
    end
  end
  generate
    if (!ONE_PORT) begin : two_ports
      assign port_ok = 1'b1;
      always_comb begin   // no single-port accesses
        op_rd = 1'b0; op_we = 1'b0; om_rd = 1'b0; om_we = 1'b0;
        for (int k = 0; k < 4; k++) begin
          op_addr[k] = '0; op_wd[k] = '0; om_addr[k] = '0; om_wd[k] = '0;
        end
      end
    end else begin : one_port          // one port each; writes that meet a read wait
      // pending row words: a pixel's own arriving while its later groups read (G - tree(5) - 1
      // at most), or, when it is taken, the last word of the pixel before (once pend is low
      // every word of that pixel has arrived but, with tree(lg(L) + [G_MAX > 1]) = 1, its last)
      localparam int QD = (G_MAX - TA - 1 > 1) ? G_MAX - TA - 1 : 1;
      localparam int QW = $clog2(QD + 1);
      localparam int AW = RAW;
      // the three top paths' memories move in step (the same cycles, their own slots)
      wire             top_on = (paths > 3'd1);       // paths 1 .. 3 read and written
      wire             rd = top_on && rd_v;
      wire             wr = top_on && row_we;
      logic [AW-1:0]   wr_addr [4];
      logic [AW-1:0]   q_addr [QD][4];
      logic [WORD-1:0] q_data [QD][4];
      logic [QW-1:0]   q_n;
      wire             from_q = !rd && (q_n != '0);
      wire             direct = !rd && (q_n == '0) && wr;
      wire             push = wr && !direct;
      always_comb
        for (int k = 0; k < 4; k++)
          wr_addr[k] = AW'(int'(wslot_q[k]) * G_MAX + int'(row_wg));
      always_comb begin
        op_rd = rd;
        op_we = from_q || direct;
        for (int k = 0; k < 4; k++) begin
          op_addr[k] = rd ? AW'(int'(take ? rslot[k] : rslot_q[k]) * G_MAX + int'(rd_g))
                     : from_q ? q_addr[0][k] : wr_addr[k];
          op_wd[k] = from_q ? q_data[0][k] : row_wd[k];
        end
      end
      always_ff @(posedge clk) begin
        if (rst) begin
          q_n <= '0;
        end else if (en) begin
          if (from_q)
            for (int i = 0; i < QD - 1; i++) begin
              q_addr[i] <= q_addr[i+1]; q_data[i] <= q_data[i+1];
            end
          if (push)
            for (int k = 1; k < 4; k++) begin
              q_addr[int'(q_n) - int'(from_q)][k] <= wr_addr[k];
              q_data[int'(q_n) - int'(from_q)][k] <= row_wd[k];
            end
          q_n <= q_n - QW'(from_q) + QW'(push);
        end
      end
      // the minima: read at a take, written once a pixel (takes are two cycles apart or more:
      // a write that meets a take's read is written in the next cycle)
      logic             mq_v;
      logic [7:0]       mq_slot [4];
      logic [PATH_W-1:0] mq_data [4];
      wire              min_rd_now = top_on && take;
      always_ff @(posedge clk) begin
        if (rst) mq_v <= 1'b0;
        else if (en) mq_v <= min_we && top_on && min_rd_now;
        if (en) begin mq_slot <= wslot_q; mq_data <= min_wd; end
      end
      always_comb begin
        om_rd = min_rd_now;
        om_we = !min_rd_now && (mq_v || (min_we && top_on));
        for (int k = 0; k < 4; k++) begin
          om_addr[k] = min_rd_now ? rslot[k] : mq_v ? mq_slot[k] : wslot_q[k];
          om_wd[k] = mq_v ? mq_data[k] : min_wd[k];
        end
      end
      // a pixel's reads take cycles t .. t + G - 1, its first word arrives in t + TA + 1: the
      // words waiting now must fit in the TA + 1 - G cycles between (no group is computed once
      // pend is low: the last group's word arrives in the cycle in_ready rises, or before)
      wire [QW:0] waiting = (QW + 1)'(q_n) + (QW + 1)'(wr);
      wire [8:0]  gap = (TA + 1 > int'(ngroups)) ? 9'(TA + 1 - int'(ngroups)) : 9'd0;
      assign port_ok = 9'(waiting) <= gap;
    end
  endgenerate

  // ---- the lane groups: predecessor lanes, five levels of arithmetic -----------------------
  // cycle t + 1 + g: group g (busy, group) with its word read in the cycle before
  wire               gv = busy;
  logic [PATH_W-1:0] res [4][D_MAX];        // the path-cost register (path 0: next's Lp)
  logic [PATH_W-1:0] edge_q [4];            // the previous group's last predecessor lane
  logic [PATH_W-1:0] mrun [4];              // the running minimum (after the fold)
  logic [PATH_W-1:0] m_left;                // the left path's minimum of the previous pixel
  always_ff @(posedge clk) begin
    if (en && gv)
      for (int k = 0; k < 4; k++)
        edge_q[k] <= (k == 0) ? res[0][int'(group) * LANES + LANES - 1]
                              : row_rd[k][(LANES - 1) * PATH_W +: PATH_W];
  end

  // level l of path k (path[k].lvl[l]), per lane: f, g, h (signed: the predecessor's L'(d),
  // L'(d - 1), L'(d + 1), then the partial results), aa (the cost A); per group: q = P1 - m'
  // (from level 1), m = m', p = P2'
  logic [PATH_W-1:0]    fin [4][LANES];     // level 5: the path costs of the group
  // the group's control through the arithmetic's TA - 1 inner registers
  logic            av_v [TA], av_last [TA];
  logic [GW-1:0]   av_g [TA];
  assign av_v[0] = gv; assign av_last[0] = (group == last_g); assign av_g[0] = group;

  genvar k, ln, l;
  generate
    for (k = 0; k < 4; k++) begin : path
      for (l = 0; l <= 5; l++) begin : lvl
        localparam bit REG = (l > 0) && (l < 5) && (l % V == 0);
        logic signed [IW-1:0] c0 [LANES], c1 [LANES], c2 [LANES], cq, cm, cp;
        logic [A_W-1:0]       ca [LANES];
        if (l == 0) begin : leaves
          always_comb begin
            cm = start_q[k] ? '0 : $signed({{(IW - PATH_W){1'b0}},
                                             (k == 0) ? m_left : min_rd[k]});
            cp = $signed({{(IW - 16){1'b0}}, pen_q[k]});
            cq = '0;
            for (int i = 0; i < LANES; i++) begin
              int d;
              logic [PATH_W-1:0] here, below, above;
              d = int'(group) * LANES + i;
              if (k == 0) begin
                here = (d < D_MAX) ? res[0][d] : BIG;
                below = (i == 0) ? edge_q[0] : ((d - 1 < D_MAX) ? res[0][d - 1] : BIG);
                above = (d + 1 < D_MAX) ? res[0][d + 1] : BIG;
              end else begin
                here = row_rd[k][i * PATH_W +: PATH_W];
                below = (i == 0) ? edge_q[k] : row_rd[k][(i - 1) * PATH_W +: PATH_W];
                above = row_rd[k][(i + 1) * PATH_W +: PATH_W];
              end
              if (start_q[k]) begin here = '0; below = '0; above = '0; end
              if (d == 0) below = BIG;
              if (d + 1 >= int'(dn)) above = BIG;
              c0[i] = $signed({{(IW - PATH_W){1'b0}}, here});
              c1[i] = $signed({{(IW - PATH_W){1'b0}}, below});
              c2[i] = $signed({{(IW - PATH_W){1'b0}}, above});
              ca[i] = (d < D_MAX) ? a_q[d * A_W +: A_W] : '0;
            end
          end
        end else begin : level
          always_comb begin
            cq = path[k].lvl[l-1].q; cm = path[k].lvl[l-1].m; cp = path[k].lvl[l-1].p;
            for (int i = 0; i < LANES; i++) begin
              logic signed [IW-1:0] x0, x1, x2;
              x0 = path[k].lvl[l-1].f[i]; x1 = path[k].lvl[l-1].g[i];
              x2 = path[k].lvl[l-1].h[i];
              ca[i] = path[k].lvl[l-1].aa[i];
              c0[i] = x0; c1[i] = x1; c2[i] = x2;
              case (l)
                1: begin   // Lp(d) - m'; min(Lp(d - 1), Lp(d + 1)); P1 - m'
                  c0[i] = x0 - cm;
                  c1[i] = (x1 < x2) ? x1 : x2;
                  cq = $signed({{(IW - 15){1'b0}}, p1}) - cm;
                end
                2: begin   // min(., P2'); + (P1 - m')
                  c0[i] = (x0 < cp) ? x0 : cp;
                  c1[i] = x1 + cq;
                end
                3: c0[i] = (x0 < x1) ? x0 : x1;                    // best - m'
                4: c0[i] = x0 + $signed({{(IW - A_W){1'b0}}, ca[i]});  // + A
                default: c0[i] = (x0 > $signed({{(IW - PATH_W){1'b0}}, BIG}))  // cap
                                 ? $signed({{(IW - PATH_W){1'b0}}, BIG}) : x0;
              endcase
            end
          end
        end
        logic signed [IW-1:0] f [LANES], g [LANES], h [LANES], q, m, p;
        logic [A_W-1:0]       aa [LANES];
        if (REG) begin : pipe
          always_ff @(posedge clk) if (en) begin
            f <= c0; g <= c1; h <= c2; aa <= ca; q <= cq; m <= cm; p <= cp;
          end
        end else begin : wire_
          assign f = c0; assign g = c1; assign h = c2; assign aa = ca; assign q = cq;
          assign m = cm;
          assign p = cp;
        end
      end
      for (ln = 0; ln < LANES; ln++) begin : out
        assign fin[k][ln] = PATH_W'(path[k].lvl[5].f[ln]);
      end
    end
  endgenerate
  genvar t;
  generate
    for (t = 1; t < TA; t++) begin : av_pipe
      always_ff @(posedge clk) begin
        if (rst) av_v[t] <= 1'b0;
        else if (en) av_v[t] <= av_v[t-1];
        if (en) begin av_last[t] <= av_last[t-1]; av_g[t] <= av_g[t-1]; end
      end
    end
  endgenerate

  // ---- the path-cost register and the group's copy; the memories' writes ------------------
  logic              rv, rlast;           // a group registered (visible this cycle)
  logic [GW-1:0]     rg;
  logic [PATH_W-1:0] gres [4][LANES];
  always_ff @(posedge clk) begin
    if (rst) rv <= 1'b0;
    else if (en) rv <= av_v[TA - 1];
    if (en) begin
      rlast <= av_last[TA - 1]; rg <= av_g[TA - 1];
      if (av_v[TA - 1])
        for (int kk = 0; kk < 4; kk++)
          for (int i = 0; i < LANES; i++) begin
            gres[kk][i] <= fin[kk][i];
            if (int'(av_g[TA - 1]) * LANES + i < D_MAX)
              res[kk][int'(av_g[TA - 1]) * LANES + i] <= fin[kk][i];
          end
    end
  end
  // word g: the group's lanes and the next group's first cost (computed now), or BIG
  always_comb begin
    row_we = rv;
    row_wg = rg;
    for (int kk = 0; kk < 4; kk++) begin
      for (int i = 0; i < LANES; i++) row_wd[kk][i * PATH_W +: PATH_W] = gres[kk][i];
      row_wd[kk][LANES * PATH_W +: PATH_W] = rlast ? BIG : fin[kk][0];
    end
  end

  // ---- the minimum over the group's lanes, the fold: tree(lg(L) + [G_MAX > 1]) -------------
  generate
    for (k = 0; k < 4; k++) begin : mn
      for (l = 0; l <= ML; l++) begin : lvl
        localparam bit REG = (l > 0) && (l < ML) && (l % V == 0);
        logic [PATH_W-1:0] c [LN];
        logic [PATH_W-1:0] p [LN];
        logic              cv, cl, cf, v, last, first;
        if (l == 0) begin : leaves
          for (ln = 0; ln < LN; ln++) begin : leaf
            always_comb begin
              c[ln] = BIG;
              if (ln < LANES && int'(rg) * LANES + ln < int'(dn)) c[ln] = gres[k][ln];
            end
          end
          assign cv = rv; assign cl = rlast; assign cf = (rg == '0);
        end else begin : node
          for (ln = 0; ln < LN; ln++) begin : n
            if (l <= LGL && ln < (LN >> l)) begin : live
              assign c[ln] = (mn[k].lvl[l-1].p[2*ln] < mn[k].lvl[l-1].p[2*ln+1])
                           ? mn[k].lvl[l-1].p[2*ln] : mn[k].lvl[l-1].p[2*ln+1];
            end else if (l > LGL && ln == 0) begin : fold   // with the running minimum
              assign c[ln] = (mn[k].lvl[l-1].first || mn[k].lvl[l-1].p[0] < mrun[k])
                           ? mn[k].lvl[l-1].p[0] : mrun[k];
            end else begin : idle
              assign c[ln] = BIG;
            end
          end
          assign cv = mn[k].lvl[l-1].v; assign cl = mn[k].lvl[l-1].last;
          assign cf = mn[k].lvl[l-1].first;
        end
        if (REG) begin : pipe
          always_ff @(posedge clk) begin
            if (rst) v <= 1'b0;
            else if (en) v <= cv;
            if (en) begin p <= c; last <= cl; first <= cf; end
          end
        end else begin : wire_
          assign p = c; assign v = cv; assign last = cl; assign first = cf;
        end
      end
    end
  endgenerate
  // the last group's token in each cycle of the tree: j = 0 its leaves, j the j-th register
  logic tree_tok [TT + 1];
  assign tree_tok[0] = rv && rlast;
  generate
    for (l = 1; l < ML; l++) begin : tok
      if (l % V == 0) begin : at_reg
        assign tree_tok[l / V] = mn[0].lvl[l].v && mn[0].lvl[l].last;
      end
    end
  endgenerate
  assign tree_tok[TT] = 1'b0;
  // the running minimum register ends the tree; a pixel's minimum after its last group
  always_ff @(posedge clk) begin
    if (en) begin
      if (mn[0].lvl[ML].v) mrun <= min_wd;
      if (mn[0].lvl[ML].v && mn[0].lvl[ML].last) m_left <= min_wd[0];
    end
  end
  assign min_we = mn[0].lvl[ML].v && mn[0].lvl[ML].last;
  generate
    for (k = 0; k < 4; k++) begin : mfin
      assign min_wd[k] = mn[k].lvl[ML].p[0];
    end
  endgenerate

  // in_ready: no group of the pixel before still to start, and its minimum registered by the
  // end of this cycle (the next pixel's group 0 reads it in the cycle after): the last group's
  // token anywhere in the arithmetic (busy: its first cycle) or in the minimum's tree but its
  // last cycle holds the next pixel
  logic pend;
  always_comb begin
    pend = busy;
    for (int i = 1; i < TA; i++) pend = pend || (av_v[i] && av_last[i]);
    for (int j = 0; j < TT - 1; j++) pend = pend || tree_tok[j];
  end
  assign take = en && in_valid && in_ready;
  assign in_ready = !pend && port_ok;

  // ---- the path costs out; the path sum: tree(3) -------------------------------------------
  always_ff @(posedge clk) begin
    if (rst) lc_valid <= 1'b0;
    else if (en) lc_valid <= av_v[TA - 1] && av_last[TA - 1];
  end
  always_comb
    for (int kk = 0; kk < 4; kk++)
      for (int d = 0; d < D_MAX; d++) lc[(kk * D_MAX + d) * PATH_W +: PATH_W] = res[kk][d];

  localparam int SW = PATH_W + 2;
  logic [SUM_W-1:0] lane_s [LANES];
  generate
    for (ln = 0; ln < LANES; ln++) begin : ps
      for (l = 0; l <= 3; l++) begin : lvl
        localparam bit REG = (l > 0) && (l < 3) && (l % V == 0);
        logic [SW-1:0] c [4];
        logic [SW-1:0] p [4];
        if (l == 0) begin : leaves
          for (k = 0; k < 4; k++) begin : leaf
            assign c[k] = (k < int'(paths)) ? SW'(gres[k][ln]) : '0;
          end
        end else if (l < 3) begin : add
          for (k = 0; k < 4; k++) begin : n
            if (k < (4 >> l)) begin : live
              assign c[k] = ps[ln].lvl[l-1].p[2*k] + ps[ln].lvl[l-1].p[2*k+1];
            end else begin : idle
              assign c[k] = '0;
            end
          end
        end else begin : saturate
          assign c[0] = (ps[ln].lvl[2].p[0] > SW'((1 << SUM_W) - 1)) ? SW'((1 << SUM_W) - 1)
                                                                     : ps[ln].lvl[2].p[0];
          for (k = 1; k < 4; k++) begin : idle
            assign c[k] = '0;
          end
        end
        if (REG) begin : pipe
          always_ff @(posedge clk) if (en) p <= c;
        end else begin : wire_
          assign p = c;
        end
      end
      assign lane_s[ln] = SUM_W'(ps[ln].lvl[3].p[0]);
    end
  endgenerate
  logic            sp_v [TP], sp_last [TP];
  logic [GW-1:0]   sp_g [TP];
  assign sp_v[0] = rv; assign sp_last[0] = rlast; assign sp_g[0] = rg;
  generate
    for (t = 1; t < TP; t++) begin : sp_pipe
      always_ff @(posedge clk) begin
        if (rst) sp_v[t] <= 1'b0;
        else if (en) sp_v[t] <= sp_v[t-1];
        if (en) begin sp_last[t] <= sp_last[t-1]; sp_g[t] <= sp_g[t-1]; end
      end
    end
  endgenerate
  always_ff @(posedge clk) begin
    if (rst) begin
      s_valid <= 1'b0;
    end else if (en) begin
      s_valid <= sp_v[TP - 1] && sp_last[TP - 1];
      if (sp_v[TP - 1])
        for (int i = 0; i < LANES; i++)
          if (int'(sp_g[TP - 1]) * LANES + i < D_MAX)
            s[(int'(sp_g[TP - 1]) * LANES + i) * SUM_W +: SUM_W] <= lane_s[i];
    end
  end
endmodule
