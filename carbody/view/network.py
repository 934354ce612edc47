"""MobileNetV2 (Sandler et al., "MobileNetV2: Inverted Residuals and Linear Bottlenecks", 2018).

Defined here with plain torch because torchvision does not install beside the CPU torch. The
layer table, channel rounding and head follow the paper and torchvision's reference
implementation exactly, so at 1000 classes and width 1.0 the network has 3,504,872 parameters;
with K classes it has 3,504,872 − 1281·(1000 − K).

Blocks: a 3×3 stride-2 stem (32 ch), then inverted residuals (1×1 expansion by t, 3×3
depthwise, 1×1 *linear* projection — no activation after it; a skip connection when the stride
is 1 and the width is unchanged), a 1×1 conv to 1280, global average pooling, dropout, linear.
"""
from __future__ import annotations

#: (t expansion, c output channels, n repeats, s first stride) — Table 2 of the paper.
INVERTED_RESIDUAL_SETTING = (
    (1, 16, 1, 1),
    (6, 24, 2, 2),
    (6, 32, 3, 2),
    (6, 64, 4, 2),
    (6, 96, 3, 1),
    (6, 160, 3, 2),
    (6, 320, 1, 1),
)


def make_divisible(value: float, divisor: int = 8, min_value: int | None = None) -> int:
    """Round a channel count to a multiple of ``divisor``, never more than 10 % below ``value``."""
    min_value = min_value or divisor
    new = max(min_value, int(value + divisor / 2) // divisor * divisor)
    if new < 0.9 * value:
        new += divisor
    return new


def expected_parameter_count(num_classes: int) -> int:
    """Parameters of the reference MobileNetV2 (width 1.0) with a ``num_classes`` head."""
    return 3_504_872 - 1281 * (1000 - num_classes)


def build_mobilenet_v2(num_classes: int = 1000, width_mult: float = 1.0, dropout: float = 0.2):
    """A ``torch.nn.Module`` MobileNetV2; input (B, 3, H, W) float, output (B, num_classes) logits."""
    import torch
    from torch import nn

    def conv_bn_relu(cin: int, cout: int, kernel: int = 3, stride: int = 1, groups: int = 1) -> nn.Sequential:
        return nn.Sequential(
            nn.Conv2d(cin, cout, kernel, stride, (kernel - 1) // 2, groups=groups, bias=False),
            nn.BatchNorm2d(cout),
            nn.ReLU6(inplace=True),
        )

    class InvertedResidual(nn.Module):
        def __init__(self, cin: int, cout: int, stride: int, expand: int):
            super().__init__()
            hidden = int(round(cin * expand))
            self.use_skip = stride == 1 and cin == cout
            layers: list[nn.Module] = []
            if expand != 1:
                layers.append(conv_bn_relu(cin, hidden, kernel=1))
            layers += [
                conv_bn_relu(hidden, hidden, stride=stride, groups=hidden),   # depthwise
                nn.Conv2d(hidden, cout, 1, 1, 0, bias=False),                 # linear bottleneck
                nn.BatchNorm2d(cout),
            ]
            self.conv = nn.Sequential(*layers)

        def forward(self, x):
            return x + self.conv(x) if self.use_skip else self.conv(x)

    class MobileNetV2(nn.Module):
        def __init__(self):
            super().__init__()
            cin = make_divisible(32 * width_mult)
            self.last_channel = make_divisible(1280 * max(1.0, width_mult))
            features: list[nn.Module] = [conv_bn_relu(3, cin, stride=2)]
            for t, c, n, s in INVERTED_RESIDUAL_SETTING:
                cout = make_divisible(c * width_mult)
                for i in range(n):
                    features.append(InvertedResidual(cin, cout, s if i == 0 else 1, t))
                    cin = cout
            features.append(conv_bn_relu(cin, self.last_channel, kernel=1))
            self.features = nn.Sequential(*features)
            self.classifier = nn.Sequential(nn.Dropout(dropout), nn.Linear(self.last_channel, num_classes))
            for m in self.modules():
                if isinstance(m, nn.Conv2d):
                    nn.init.kaiming_normal_(m.weight, mode="fan_out")
                elif isinstance(m, nn.BatchNorm2d):
                    nn.init.ones_(m.weight)
                    nn.init.zeros_(m.bias)
                elif isinstance(m, nn.Linear):
                    nn.init.normal_(m.weight, 0, 0.01)
                    nn.init.zeros_(m.bias)

        def forward(self, x):
            x = self.features(x)
            x = torch.flatten(nn.functional.adaptive_avg_pool2d(x, 1), 1)
            return self.classifier(x)

    return MobileNetV2()
